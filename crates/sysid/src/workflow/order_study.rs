//! A measurement, not a check: the one-step validation fit of
//! state-space models against their order on logs imported by
//! `kestrel import` (first half of each experiment to estimate, second
//! half to validate, as `scripts/flight-logs.sh`), beside the best ARX
//! of 2-10 lags and its state count (`docs/sysid.md`, "The one-step gap
//! to ARX"). Run with
//!
//! ```text
//! KESTREL_ORDER_STUDY=a.csv,b.csv [KESTREL_ORDER_STUDY_ORDERS=2,4,8] \
//!   [KESTREL_ORDER_STUDY_HORIZON=5] [KESTREL_ORDER_STUDY_COLUMNS=sr,pb,rr,arx,ms,mr] \
//!   cargo test --release -p kestrel-sysid order_study -- --ignored --nocapture
//! ```
//!
//! Columns per order `n`: one-step PEM (innovation form, 30 iterations)
//! from the N4SID state-regression start, from PBSID, and from the
//! state regression with `|eig A| <= 1.02`; the best ARX's realisation
//! reduced to `n` states ([`arx_reduction`]: `balred` with the noise
//! channels balanced too, `K` refitted with the dynamics fixed, an
//! unstable ARX realisation's modes beyond 0.999 moved inside first),
//! and the same then refined by one-step PEM. With `KESTREL_ORDER_STUDY_HORIZON=h` two multi-step
//! columns follow, the default choice's multi-step candidates: PEM over
//! the `1..=h`-step predictions then `K` by one-step prediction, and PEM
//! over the `1..=h`-step predictions with `|eig A| <= 1.02`, both from
//! the state-regression start. `KESTREL_ORDER_STUDY_COLUMNS` keeps only
//! the named columns (`sr`, `pb`, `rr`, `arx`, `ms`, `mr`; the slow
//! ones are worth leaving out at 500 Hz). Every figure is the mean fit over the outputs on the validation
//! half, percent (1-step / 5-step).

use super::fit::fit_structure;
use super::spec::{IdentifySpec, Method, PemFocus, Start};
use crate::arx::{ArxSettings, arx, arx_baseline};
use crate::closed_loop::{ArxReductionSettings, arx_reduction};
use crate::data::{CsvColumns, Experiment, IoData};
use crate::error::Result;
use crate::model::InnovationModel;
use crate::n4sid::MatrixEstimate;
use crate::pem::{PemSettings, pem};
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

/// PEM at order `n` from `start` with the given focus and
/// `pem_horizon`.
fn pem_focus(
    est: &IoData,
    val: &IoData,
    n: usize,
    (start, m): (Start, MatrixEstimate),
    r: Option<f64>,
    focus: PemFocus,
    pem_horizon: usize,
) -> String {
    let spec = IdentifySpec {
        order: Some(n),
        method: Method::Pem,
        start,
        n4sid_matrices: m,
        focus,
        pem_horizon,
        max_iterations: 30,
        auto: None,
        ..Default::default()
    };
    match fit_structure(est, &spec, r) {
        Ok(f) => fits(&f.model, val),
        Err(e) => format!("failed: {e}"),
    }
}

/// The ARX of `lags` lags reduced to `n` states, `K` refitted
/// ([`arx_reduction`]); then all refined by one-step PEM.
fn arx_reduced(est: &IoData, val: &IoData, lags: usize, n: usize) -> (String, String) {
    let s = ArxReductionSettings {
        order: Some(n),
        lags,
        ..Default::default()
    };
    let k = match arx_reduction(est, &s) {
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
    let horizon: Option<usize> = std::env::var("KESTREL_ORDER_STUDY_HORIZON")
        .ok()
        .map(|s| s.trim().parse().expect("a horizon"));
    let columns = std::env::var("KESTREL_ORDER_STUDY_COLUMNS")
        .unwrap_or_else(|_| "sr,pb,rr,arx,ms,mr".into());
    let wanted = |c: &str| columns.split(',').any(|x| x.trim() == c);
    let skipped = || "(skipped)".to_string();
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
        let h = horizon.unwrap_or(0);
        println!(
            "| order | PEM from N4SID state regression | PEM from PBSID | PEM, state regression, radius 1.02 | ARX({lags}) balred, K refitted | ARX({lags}) balred, PEM |{}",
            if h > 0 {
                format!(" PEM 1..{h} then K | PEM 1..{h}, radius 1.02 |")
            } else {
                String::new()
            }
        );
        println!(
            "|---|---|---|---|---|---|{}",
            if h > 0 { "---|---|" } else { "" }
        );
        let sr_start = (Start::N4sid, MatrixEstimate::StateRegression);
        for &n in &orders {
            let t = std::time::Instant::now();
            let one = |c: &str, r: Option<f64>, start| {
                if wanted(c) {
                    pem_focus(&est, &val, n, start, r, PemFocus::Prediction, 1)
                } else {
                    skipped()
                }
            };
            let sr = one("sr", None, sr_start);
            let pb = one("pb", None, (Start::Pbsid, MatrixEstimate::OutputError));
            let rr = one("rr", Some(1.02), sr_start);
            let (ak, ap) = if !wanted("arx") {
                (skipped(), String::new())
            } else if n < full.nx() {
                arx_reduced(&est, &val, lags, n)
            } else {
                ("(order >= ARX states)".into(), String::new())
            };
            let multi = if h == 0 {
                String::new()
            } else {
                let ms = if wanted("ms") {
                    let focus = PemFocus::MultiStepThenNoise { horizon: h };
                    pem_focus(&est, &val, n, sr_start, None, focus, 1)
                } else {
                    skipped()
                };
                let mr = if wanted("mr") {
                    let focus = PemFocus::Prediction;
                    pem_focus(&est, &val, n, sr_start, Some(1.02), focus, h)
                } else {
                    skipped()
                };
                format!(" {ms} | {mr} |")
            };
            println!(
                "| {n} | {sr} | {pb} | {rr} | {ak} | {ap} |{multi}  ({:.0} s)",
                t.elapsed().as_secs_f64()
            );
        }
    }
}
