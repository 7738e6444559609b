//! The set-up of the steam generator example: the data file and its
//! halves, the folds of the blocked cross-validation, the state-regression
//! N4SID start of order 9, a timed PEM call, the validation figures
//! against the targets of the issue (simulation 74.4 %, 1-step 94.1 %,
//! 5-step 88.9 %), the grid's lists read from the environment, the worker
//! threads that fit the candidates and the choice by the inner score.

use kestrel_sysid::{
    CsvColumns, InnovationModel, IoData, MatrixEstimate, N4sidSettings, PemResult, PemSettings,
    Weighting, n4sid, pem, validate,
};
use std::path::PathBuf;

/// The model order (as in issue 4).
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
/// shared DaISy file `../shared/data/daisy/steam_generator.csv` beside the
/// repository) and splits it in halves: estimate on the first,
/// validate on the second.
pub fn halves() -> Result<Halves, Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../../shared/data/daisy/steam_generator.csv")
        });
    let cols = CsvColumns::new(&["u1", "u2", "u3", "u4"], &["y1", "y2", "y3", "y4"]);
    let data = IoData::read_csv(&path, &cols)?;
    let (est, val) = data.split(0.5)?;
    let (est, off) = est.remove_means()?;
    let val = val.subtract(&off)?;
    Ok(Halves { est, val })
}

/// Blocked cross-validation inside the estimation half: `est` cut into
/// `k` consecutive blocks; fold `j` fits on every block but the `j`-th
/// (each block its own experiment, their common means removed) and
/// scores on block `j` (the same offsets subtracted).
pub fn folds(est: &IoData, k: usize) -> Result<Vec<Halves>, Box<dyn std::error::Error>> {
    let mut blocks = Vec::with_capacity(k);
    let mut rest = est.clone();
    for j in 0..k.saturating_sub(1) {
        let (b, r) = rest.split(1.0 / (k - j) as f64)?;
        blocks.push(b);
        rest = r;
    }
    blocks.push(rest);
    (0..blocks.len())
        .map(|j| {
            let others: Vec<IoData> = (0..blocks.len())
                .filter(|&o| o != j)
                .map(|o| blocks[o].clone())
                .collect();
            let (fit, off) = IoData::merge(&others)?.remove_means()?;
            Ok(Halves {
                est: fit,
                val: blocks[j].subtract(&off)?,
            })
        })
        .collect()
}

/// The comma-separated list in the environment variable `var` (or
/// `default` when it is not set), every entry read by `parse`.
pub fn list<T>(
    var: &str,
    default: &str,
    parse: impl Fn(&str) -> Option<T>,
) -> Result<Vec<T>, String> {
    std::env::var(var)
        .unwrap_or_else(|_| default.into())
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| parse(s.trim()).ok_or(format!("{var}: cannot read {s:?}")))
        .collect()
}

/// An N4SID start of the grids written `weighting:i`: `moesp:10`,
/// `cva:20`, `unweighted:5`.
pub fn weighting_start(s: &str) -> Option<(Weighting, usize)> {
    let (w, i) = s.split_once(':')?;
    let weighting = match w {
        "moesp" => Weighting::Moesp,
        "cva" => Weighting::Cva,
        "unweighted" => Weighting::Unweighted,
        _ => return None,
    };
    Some((weighting, i.parse().ok()?))
}

/// Prediction steps written `a+b+...` (each at least 1): `1+5`,
/// `1+5+10`.
pub fn step_list(s: &str) -> Option<Vec<usize>> {
    s.split('+')
        .map(|k| k.parse::<usize>().ok().filter(|&k| k > 0))
        .collect()
}

/// The number in the environment variable `var`, or `default` when it
/// is not set or not a number.
pub fn env_number(var: &str, default: usize) -> usize {
    std::env::var(var)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Whether the chosen candidate is refitted and validated (`STEAM_REFIT=0`
/// stops after the inner table).
pub fn refit() -> bool {
    std::env::var("STEAM_REFIT").map_or(true, |v| v != "0")
}

/// Runs `work` on every job on `threads` worker threads that take the
/// jobs in turn, in the order given. Returns the results in the order the
/// jobs finish; a job that fails is left out and its error printed to
/// stderr after its `label`.
pub fn in_threads<J: Sync, T: Send>(
    jobs: &[J],
    threads: usize,
    label: impl Fn(&J) -> String + Sync,
    work: impl Fn(&J) -> Result<T, String> + Sync,
) -> Result<Vec<T>, &'static str> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    let Some(job) = jobs.get(i) else {
                        break;
                    };
                    let r = work(job);
                    if let Ok(mut all) = results.lock() {
                        match r {
                            Ok(v) => all.push(v),
                            Err(e) => eprintln!("{}: {e}", label(job)),
                        }
                    }
                }
            });
        }
    });
    results.into_inner().map_err(|_| "poisoned")
}

/// Prints a line of the inner table for every candidate (`row`, given the
/// candidate, its result and its score, the sum of the mean fits that
/// `fits` takes from its result) and returns the best finite score with
/// its candidate (the first of equal scores).
pub fn choose<C, R>(
    rows: &[(C, R)],
    fits: impl Fn(&R) -> &Fits,
    row: impl Fn(&C, &R, f64) -> String,
) -> Result<(f64, &C), &'static str> {
    let mut best: Option<(f64, &C)> = None;
    for (c, r) in rows {
        let score = fits(r).score();
        println!("{}", row(c, r, score));
        if score.is_finite() && best.is_none_or(|(s, _)| score > s) {
            best = Some((score, c));
        }
    }
    best.ok_or("no configuration")
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

/// The chosen configuration's refit: [`timed_pem`] from `start` on the
/// whole estimation half `est` (labelled `refit <label>`), validated once
/// on `val` by [`table`] with its iterations, stop reason and the time
/// since `since`.
pub fn refit_and_validate(
    est: &IoData,
    val: &IoData,
    start: &InnovationModel,
    settings: &PemSettings,
    label: &str,
    since: std::time::Instant,
) -> Result<(), Box<dyn std::error::Error>> {
    let r = timed_pem(est, start, settings, &format!("refit {label}"))?;
    table(
        &format!(
            "{label} ({} iterations, stop {:?}, {:.1} s)",
            r.iterations,
            r.stop,
            since.elapsed().as_secs_f64()
        ),
        &r.model,
        val,
    )
}

/// The state-regression N4SID start ([`MatrixEstimate::StateRegression`])
/// of `order` with feed-through, `weighting` and `i` block rows.
pub fn regression_start(
    est: &IoData,
    order: usize,
    weighting: Weighting,
    i: usize,
) -> Result<InnovationModel, String> {
    n4sid(
        est,
        &N4sidSettings {
            order: Some(order),
            horizon: Some(i),
            weighting,
            feedthrough: true,
            matrices: MatrixEstimate::StateRegression,
            ..Default::default()
        },
    )
    .map(|r| r.model)
    .map_err(|e| e.to_string())
}
