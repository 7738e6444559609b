//! A measurement, not a check: the one-step validation fit of
//! state-space models against their order on logs imported by
//! `kestrel import` (first half of each experiment to estimate, second
//! half to validate, as `scripts/flight-logs.sh`), beside the best ARX
//! of 2-10 lags and its state count (`docs/sysid.md`, "The one-step gap
//! to ARX"). Run with
//!
//! ```text
//! KESTREL_ORDER_STUDY=a.csv,b.csv [KESTREL_ORDER_STUDY_ORDERS=2,4,8] \
//!   cargo test --release -p kestrel-sysid order_study -- --ignored --nocapture
//! ```
//!
//! Columns per order `n`: one-step PEM (innovation form, 30 iterations)
//! from the N4SID state-regression start, from PBSID, and from the
//! state regression with `|eig A| <= 1.02`; the best ARX's realisation
//! reduced to `n` states by `balred` (noise channels balanced too) with
//! `K` refitted (dynamics fixed), and the same then refined by one-step
//! PEM (an unstable ARX realisation has its modes beyond 0.999 moved
//! inside first). Every figure is the mean fit over the outputs on the validation
//! half, percent (1-step / 5-step).

use super::fit::fit_structure;
use super::spec::{IdentifySpec, Method, PemFocus, Start};
use crate::arx::{ArxSettings, arx, arx_baseline};
use crate::closed_loop::stabilise_a;
use crate::data::{CsvColumns, Experiment, IoData};
use crate::error::Result;
use crate::model::InnovationModel;
use crate::n4sid::MatrixEstimate;
use crate::pem::{Focus, PemSettings, pem};
use crate::reduce::{BalredSettings, ReductionMethod, balred};
use crate::validate::{persistence_fit, predict_fit};

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// `(est, val)`: the first and second half of every experiment, the
/// estimation means removed from both.
fn halves(data: &IoData) -> Result<(IoData, IoData)> {
    let mut a = Vec::new();
    let mut b = Vec::new();
    for e in data.experiments() {
        let h = e.len() / 2;
        if h < 2 {
            continue;
        }
        let part = |s: usize, n: usize| Experiment {
            t: e.t[s..s + n].to_vec(),
            u: e.u.rows(s, n).into_owned(),
            y: e.y.rows(s, n).into_owned(),
        };
        a.push(part(0, h));
        b.push(part(h, e.len() - h));
    }
    let mk = |x| {
        IoData::from_experiments(
            data.ts(),
            data.input_names().to_vec(),
            data.output_names().to_vec(),
            x,
        )
    };
    let (est, off) = mk(a)?.remove_means()?;
    Ok((est, mk(b)?.subtract(&off)?))
}

fn fits(model: &InnovationModel, val: &IoData) -> String {
    let f = |k| predict_fit(model, val, k).map(|v| mean(&v));
    match (f(1), f(5)) {
        (Ok(a), Ok(b)) => format!("{a:.2} / {b:.2}"),
        (Err(e), _) | (_, Err(e)) => format!("failed: {e}"),
    }
}

fn pem_from(
    est: &IoData,
    val: &IoData,
    n: usize,
    start: Start,
    m: MatrixEstimate,
    r: Option<f64>,
) -> String {
    let spec = IdentifySpec {
        order: Some(n),
        method: Method::Pem,
        start,
        n4sid_matrices: m,
        focus: PemFocus::Prediction,
        pem_horizon: 1,
        max_iterations: 30,
        auto: None,
        ..Default::default()
    };
    match fit_structure(est, &spec, r) {
        Ok(f) => fits(&f.model, val),
        Err(e) => format!("failed: {e}"),
    }
}

/// The ARX realisation reduced to `n`, `K` refitted; then all refined.
/// An unstable realisation (`balred` needs a stable `A`) has its modes
/// beyond radius 0.999 moved inside first ([`stabilise_a`]).
fn arx_reduced(est: &IoData, val: &IoData, full: &InnovationModel, n: usize) -> (String, String) {
    let stable = match stabilise_a(full, 0.999) {
        Ok(m) => m,
        Err(e) => return (format!("failed: {e}"), String::new()),
    };
    let red = match balred(
        &stable,
        n,
        &BalredSettings {
            method: ReductionMethod::Truncate,
            include_noise: true,
        },
    ) {
        Ok(r) => r.model,
        Err(e) => return (format!("failed: {e}"), String::new()),
    };
    let noise = PemSettings {
        focus: Focus::Prediction,
        fixed_dynamics: true,
        ..Default::default()
    };
    let k = match pem(est, &red, &noise) {
        Ok(r) => r.model,
        Err(e) => return (format!("failed: {e}"), String::new()),
    };
    let all = match pem(est, &k, &PemSettings::default()) {
        Ok(r) => fits(&r.model, val),
        Err(e) => format!("failed: {e}"),
    };
    (fits(&k, val), all)
}

#[test]
#[ignore = "a measurement on real logs (minutes); see the module documentation"]
fn order_study() {
    let Ok(paths) = std::env::var("KESTREL_ORDER_STUDY") else {
        eprintln!("KESTREL_ORDER_STUDY not set: nothing to measure");
        return;
    };
    let orders: Vec<usize> = std::env::var("KESTREL_ORDER_STUDY_ORDERS")
        .unwrap_or_else(|_| "2,3,4,5,6,7,8,10,12,15,20".into())
        .split(',')
        .map(|s| s.trim().parse().expect("an order"))
        .collect();
    for path in paths.split(',') {
        let header = std::fs::read_to_string(path).expect("the CSV");
        let names: Vec<&str> = header
            .lines()
            .next()
            .expect("a header")
            .split(',')
            .collect();
        let data = IoData::read_csv(
            std::path::Path::new(path),
            &CsvColumns::new(&names[1..5], &["p", "q", "r"]),
        )
        .expect("the log");
        let (est, val) = halves(&data).expect("halves");
        let base = arx_baseline(&est, &val, 2..=10, &[1, 5]).expect("ARX");
        let (r1, r5) = (base.row(1).unwrap(), base.row(5).unwrap());
        let lags = r1.lags;
        let full = arx(&est, &ArxSettings::lags(lags))
            .and_then(|m| m.to_innovation_model())
            .expect("the ARX realisation");
        println!(
            "\n{path}: {} estimation samples; persistence {:.2} / {:.2}; best ARX 1-step {:.2} ({} lags = {} states as realised), 5-step {:.2} ({} lags); the ARX realisation itself {}",
            est.n_samples(),
            mean(&persistence_fit(&val, Some(1))),
            mean(&persistence_fit(&val, Some(5))),
            r1.mean,
            lags,
            full.nx(),
            r5.mean,
            r5.lags,
            fits(&full, &val),
        );
        println!(
            "| order | PEM from N4SID state regression | PEM from PBSID | PEM, state regression, radius 1.02 | ARX({lags}) balred, K refitted | ARX({lags}) balred, PEM |"
        );
        println!("|---|---|---|---|---|---|");
        for &n in &orders {
            let t = std::time::Instant::now();
            let sr = pem_from(
                &est,
                &val,
                n,
                Start::N4sid,
                MatrixEstimate::StateRegression,
                None,
            );
            let pb = pem_from(
                &est,
                &val,
                n,
                Start::Pbsid,
                MatrixEstimate::OutputError,
                None,
            );
            let rr = pem_from(
                &est,
                &val,
                n,
                Start::N4sid,
                MatrixEstimate::StateRegression,
                Some(1.02),
            );
            let (ak, ap) = if n < full.nx() {
                arx_reduced(&est, &val, &full, n)
            } else {
                ("(order >= ARX states)".into(), String::new())
            };
            println!(
                "| {n} | {sr} | {pb} | {rr} | {ak} | {ap} |  ({:.0} s)",
                t.elapsed().as_secs_f64()
            );
        }
    }
}
