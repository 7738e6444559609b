//! Grey-box identification of the simulated tricopter's physical
//! parameters from flights no. 2 and 3 (the thesis's estimation and
//! validation intervals), started from the thesis's Table 7.1 guess, and
//! its fit table next to the black-box model of section 7.4.
//!
//! `cargo run --release -p kestrel-tricopter --example greybox [-- seconds seed]`

use kestrel_sysid::workflow::{Segment, select_segments};
use kestrel_sysid::{ValidationReport, validate};
use kestrel_tricopter::ident::greybox::{GreyBoxSpec, estimate_grey_box, grey_box_model};
use kestrel_tricopter::ident::{
    ESTIMATE, ModelKind, VALIDATE, identify_thesis_model, simulated_flights,
};
use kestrel_tricopter_model::{Experiment, GreyBoxParams, SimSettings};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seconds: f64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(250.0);
    let seed: u64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(1);
    let flights = simulated_flights(seconds, seed)?;
    let est = select_segments(&flights, &Segment::parse_list(ESTIMATE)?)?;
    let val = select_segments(&flights, &Segment::parse_list(VALIDATE)?)?;
    let offsets = est.means();
    let est = est.subtract(&offsets)?;
    let val = val.subtract(&offsets)?;
    // The parameters the simulator flies with.
    let plant = SimSettings::new(Experiment::Decoupled, seconds, seed)
        .plant
        .params;
    let truth = GreyBoxParams::from_params(&plant);
    let initial = GreyBoxParams::thesis_initial_guess();
    // All eight parameters from the rate data alone, and k_t, k_tau from
    // the operating point (the mean pulses removed from the data).
    let free = GreyBoxSpec::closed_loop_flights(plant);
    let u0 = &offsets.u0;
    let spec = GreyBoxSpec {
        operating_point: Some([u0[0], u0[1], u0[2], u0[3]]),
        ..free.clone()
    };
    let t0 = Instant::now();
    let all_free = estimate_grey_box(&est, &free, &initial)?;
    println!(
        "all eight free ({:.2} s): {}",
        t0.elapsed().as_secs_f64(),
        all_free
            .stages
            .last()
            .map(|s| format!("{:?}", s.stop))
            .unwrap_or_default()
    );
    table(&all_free, &truth);
    println!();
    let t0 = Instant::now();
    let report = estimate_grey_box(&est, &spec, &initial)?;
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "with k_t, k_tau from the operating point: grey-box PEM ({:?} focus) on {} samples in {} segments: {} iterations, stopped {:?}, {:.2} s",
        spec.focus,
        est.n_samples(),
        est.experiments().len(),
        report.iterations,
        report.stop,
        secs
    );
    if report.start_adjusted {
        println!(
            "Table 7.1 cannot hover with the known aircraft: k_tau halved to {:.4e} for the start",
            report.start.k_tau
        );
    }
    table(&report, &truth);
    let grey = report.validate(&val, &[1, 5])?;
    let black = identify_thesis_model(ModelKind::BlackBox, seconds, seed)?;
    // Reference: the simulator's own linearised model (the truth, K = 0).
    let true_model = grey_box_model(&truth, &spec, est.ts())?;
    let true_fit = validate(&true_model, &val, &[1, 5])?;
    println!("\nvalidation fit [%] (p / q / r, mean):");
    let row = |r: &ValidationReport, l: &str| r.row(l).map(|r| (r.fit.clone(), r.mean()));
    for label in ["model simulation", "model 1-step", "model 5-step"] {
        let rows = [
            ("grey-box", &grey),
            ("black-box 8 -> 5", &black.validation),
            ("truth, K = 0", &true_fit),
        ];
        for (name, rep) in rows {
            if name.starts_with("truth") && label != "model simulation" {
                continue;
            }
            if let Some((f, m)) = row(rep, label) {
                println!(
                    "{:<18}{:<18}{:>8.2}{:>8.2}{:>8.2}{:>8.2}",
                    name, label, f[0], f[1], f[2], m
                );
            }
        }
    }
    println!("\ngrey-box residual tests on the validation data:\n{grey}");
    Ok(())
}

/// The parameter table and the well-determined combinations.
fn table(report: &kestrel_tricopter::ident::greybox::GreyBoxReport, truth: &GreyBoxParams) {
    println!(
        "{:<11}{:>12}{:>12}{:>12}{:>9}{:>12}",
        "parameter", "truth", "initial", "estimate", "error %", "std error"
    );
    for (p, t) in report.parameters.iter().zip(truth.to_array()) {
        println!(
            "{:<11}{:>12.4e}{:>12.4e}{:>12.4e}{:>9.2}{:>12}",
            p.name,
            t,
            p.initial,
            p.estimate,
            100.0 * (p.estimate / t - 1.0),
            match (p.free, p.std_error) {
                (false, _) => "fixed".to_string(),
                (true, Some(s)) => format!("{s:.2e}"),
                (true, None) => "-".to_string(),
            }
        );
    }
    let comb = |g: &GreyBoxParams| {
        let s = g.k_t.sqrt();
        [
            ("sqrt(k_t)/ixx", s / g.ixx),
            ("sqrt(k_t)/iyy", s / g.iyy),
            ("k_tau/sqrt(k_t)", g.k_tau / s),
        ]
    };
    for ((name, e), (_, t)) in comb(&report.estimate).iter().zip(comb(truth)) {
        println!(
            "{:<16}{:>12.4e}{:>12.4e}{:>9.2} %",
            name,
            t,
            e,
            100.0 * (e / t - 1.0)
        );
    }
}
