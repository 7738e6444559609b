//! The step scenario of thesis 7.7.1 on the nonlinear tricopter: the MPC
//! designed from the identified 5-state model (thesis-sized and larger
//! problem, plain and offset-free, clarabel QP) against the baseline PI,
//! quiet and noisy, as a Markdown table (the README's).
//!
//! `cargo run --release -p kestrel-tricopter --example step_comparison`

use kestrel_mpc::{DisturbanceModel, MpcLaw, MpcProblem, QpSettings};
use kestrel_tricopter::closed_loop::{
    RunResult, RunSettings, fly_mpc, fly_offset_free, fly_pi, kalman_design,
    kalman_design_with_disturbance,
};
use kestrel_tricopter::{
    ProblemSize, TricopterError, default_weights, identified_model, tricopter_problem,
    tricopter_trim,
};

fn row(name: &str, run: &str, r: &RunResult) {
    let m = &r.metrics;
    let j = |v: &[f64], p: usize| {
        v.iter()
            .map(|x| format!("{x:.p$}"))
            .collect::<Vec<_>>()
            .join(" / ")
    };
    let steady = {
        let tail: Vec<_> = r.trace.rows.iter().filter(|x| x.t >= 3.0).collect();
        tail.iter()
            .map(|x| {
                (0..3)
                    .map(|k| (x.reference[k] - x.rates[k]).abs())
                    .sum::<f64>()
                    / 3.0
            })
            .sum::<f64>()
            / tail.len().max(1) as f64
    };
    println!(
        "| {name} | {run} | {} | {} | {} | {steady:.3} | {} | {:.1} |",
        j(&m.rise_time, 2),
        j(&m.overshoot, 0),
        j(&m.rms_error, 3),
        j(&m.effort, 0),
        m.max_bound_violation
    );
}

fn main() -> Result<(), TricopterError> {
    let model = identified_model()?;
    let kalman = kalman_design(&model)?;
    let (q1, q2) = default_weights();
    let trim = tricopter_trim(&model)?;
    println!(
        "| controller | run | rise time p/q/r [s] | overshoot p/q/r [%] | RMS error p/q/r [rad/s] | mean abs error t >= 3 s [rad/s] | effort pwm1/2/3/servo [us] | bound violation [us] |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (run, settings) in [
        ("quiet", RunSettings::default()),
        ("noisy", RunSettings::noisy()),
    ] {
        row("PI", run, &fly_pi(&model, &settings)?);
        for (size, name) in [
            (ProblemSize::Thesis, "MPC N=2 [2]"),
            (ProblemSize::Larger, "MPC N=10 [1,1,2,6]"),
        ] {
            let problem = tricopter_problem(&model, size, q1.clone(), q2.clone())?;
            let mut law = MpcLaw::clarabel(&problem, QpSettings::default())?;
            row(
                name,
                run,
                &fly_mpc(&model, &problem, &mut law, &kalman, &settings)?,
            );
            let design = MpcProblem::build_offset_free(
                &model,
                &trim.constrain(size.settings(q1.clone(), q2.clone())),
                &DisturbanceModel::OutputStates,
            )?;
            let mut law = MpcLaw::clarabel(&design.problem, QpSettings::default())?;
            let kalman_of = kalman_design_with_disturbance(&design.augmented, design.nd)?;
            row(
                &format!("{name} offset-free"),
                run,
                &fly_offset_free(&design, &mut law, &kalman_of, &settings)?,
            );
        }
    }
    Ok(())
}
