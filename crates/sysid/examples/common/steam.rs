//! Set-up shared by the DaISy steam generator examples (`steam`,
//! `steam_criterion`, `steam_focus`): the data file and its halves, the
//! N4SID start of order 9, a timed PEM call, and the validation figures
//! against the targets of the issue (simulation 74.4 %, 1-step 94.1 %,
//! 5-step 88.9 %). Included by each example with `#[path]`; not an example
//! of its own.

// Each example uses only part of this module.
#![allow(dead_code)]

use kestrel_sysid::{
    CsvColumns, InnovationModel, IoData, N4sidSettings, PemResult, PemSettings, n4sid, pem,
    validate,
};
use std::path::PathBuf;

/// The model order of all steam examples.
pub const ORDER: usize = 9;

/// The estimation half (its means removed) and the validation half (the
/// same offsets subtracted).
pub struct Halves {
    /// First half of the record, mean-free.
    pub est: IoData,
    /// Second half, with the estimation half's means subtracted.
    pub val: IoData,
}

/// Reads the steam generator CSV (the first command-line argument, or the
/// shared DaISy file) and splits it in halves: estimate on the first,
/// validate on the second.
pub fn halves() -> Result<Halves, Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data/daisy/steam_generator.csv"));
    let cols = CsvColumns::new(&["u1", "u2", "u3", "u4"], &["y1", "y2", "y3", "y4"]);
    let data = IoData::read_csv(&path, &cols)?;
    let (est, val) = data.split(0.5)?;
    let (est, off) = est.remove_means()?;
    let val = val.subtract(&off)?;
    Ok(Halves { est, val })
}

/// The inner split for cross-validation inside the estimation half: fit
/// on its first 2/3 (means removed), score on its last 1/3.
pub fn inner_halves(est: &IoData) -> Result<Halves, Box<dyn std::error::Error>> {
    let (inner_est, inner_val) = est.split(2.0 / 3.0)?;
    let (inner_est, inner_off) = inner_est.remove_means()?;
    let inner_val = inner_val.subtract(&inner_off)?;
    Ok(Halves {
        est: inner_est,
        val: inner_val,
    })
}

/// Mean fits over the outputs, in percent.
pub struct Fits {
    /// Simulation fit.
    pub sim: f64,
    /// One-step prediction fit.
    pub one: f64,
    /// Five-step prediction fit.
    pub five: f64,
}

impl Fits {
    /// The cross-validation score: the sum of the three fits.
    pub fn score(&self) -> f64 {
        self.sim + self.one + self.five
    }
}

/// The mean simulation, 1-step and 5-step fits of `model` on `data`.
pub fn fits(model: &InnovationModel, data: &IoData) -> Result<Fits, String> {
    let r = validate(model, data, &[1, 5]).map_err(|e| e.to_string())?;
    let mean = |l: &str| r.row(l).map(|x| x.mean()).unwrap_or(f64::NAN);
    Ok(Fits {
        sim: mean("model simulation"),
        one: mean("model 1-step"),
        five: mean("model 5-step"),
    })
}

/// Validates `model` on `val` and prints the mean fits against the
/// targets, then the whole validation table.
pub fn table(
    title: &str,
    model: &InnovationModel,
    val: &IoData,
) -> Result<(), Box<dyn std::error::Error>> {
    let r = validate(model, val, &[1, 5])?;
    let mean = |l: &str| r.row(l).map(|x| x.mean()).unwrap_or(f64::NAN);
    println!(
        "== {title}: simulation {:.2} %, 1-step {:.2} %, 5-step {:.2} % (targets 74.4, 94.1, 88.9)\n{r}",
        mean("model simulation"),
        mean("model 1-step"),
        mean("model 5-step")
    );
    Ok(())
}

/// PEM from `start` with `settings`, its iterations, stop reason and time
/// printed to stderr after `label`.
pub fn timed_pem(
    est: &IoData,
    start: &InnovationModel,
    settings: &PemSettings,
    label: &str,
) -> Result<PemResult, String> {
    let t = std::time::Instant::now();
    let r = pem(est, start, settings).map_err(|e| e.to_string())?;
    eprintln!(
        "{label}: {} iterations, stop {:?}, {:.1} s",
        r.iterations,
        r.stop,
        t.elapsed().as_secs_f64()
    );
    Ok(r)
}

/// The dynamics fit: N4SID of order [`ORDER`] with `start` (its
/// feed-through taken from `settings`), then [`timed_pem`] from it.
pub fn dynamics(
    est: &IoData,
    start: N4sidSettings,
    settings: &PemSettings,
    label: &str,
) -> Result<PemResult, String> {
    let start = n4sid(
        est,
        &N4sidSettings {
            order: Some(ORDER),
            feedthrough: settings.feedthrough,
            ..start
        },
    )
    .map_err(|e| e.to_string())?;
    timed_pem(est, &start.model, settings, label)
}
