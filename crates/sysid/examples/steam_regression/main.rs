//! The DaISy steam generator from the state-regression subspace start:
//! N4SID of order 9 with `A, B, C, D` from the state sequence and `K`
//! from its residual covariances ([`kestrel_sysid::MatrixEstimate::StateRegression`]),
//! a feed-through `D`, then PEM with the fit criterion over selected
//! prediction steps (`K` and `D` estimated), every search to
//! convergence. The start (weighting and block rows `i`) and the step set
//! are chosen by blocked cross-validation inside the estimation half: it
//! is cut into `STEAM_FOLDS` consecutive blocks (default 3), each held
//! out in turn while the others are fitted, and a candidate's score is
//! the sum of its mean simulation, 1-step and 5-step fits averaged over
//! the folds. The choice is then fitted on the whole estimation half and
//! validated once on the second half:
//!
//! `cargo run --release -p kestrel-sysid --example steam_regression [path]`
//!
//! `STEAM_STARTS` (default `moesp:5,moesp:8,moesp:10,cva:8,unweighted:5`),
//! `STEAM_STEPS` (default `1+5,1+5+10`: the steps whose errors enter
//! the criterion), `STEAM_FOLDS`, `STEAM_MAX_ITER` (default 200) and
//! `STEAM_THREADS` (default 2) set the grid; `STEAM_REFIT=0` stops after
//! the cross-validation table.

mod steam;

use kestrel_sysid::{Criterion, InnovationModel, IoData, PemSettings, Weighting};
use steam::{Fits, choose, fits, in_threads, list, table, timed_pem};

/// A candidate of the grid.
#[derive(Clone, Debug, PartialEq)]
struct Config {
    weighting: Weighting,
    /// N4SID block rows.
    i: usize,
    /// The prediction steps of the criterion.
    steps: Vec<usize>,
}

impl Config {
    fn settings(&self, max_iterations: usize) -> PemSettings {
        PemSettings {
            criterion: Criterion::Fit,
            horizon: self.steps.iter().copied().max().unwrap_or(1),
            steps: self.steps.clone(),
            feedthrough: true,
            max_iterations,
            ..Default::default()
        }
    }

    fn label(&self) -> String {
        let steps: Vec<String> = self.steps.iter().map(|k| k.to_string()).collect();
        format!(
            "{:?} i = {} | steps {}",
            self.weighting,
            self.i,
            steps.join("+")
        )
    }

    /// The state-regression N4SID start of order 9 with feed-through.
    fn start(&self, est: &IoData) -> Result<InnovationModel, String> {
        steam::regression_start(est, steam::ORDER, self.weighting, self.i)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let starts = list(
        "STEAM_STARTS",
        "moesp:5,moesp:8,moesp:10,cva:8,unweighted:5",
        steam::weighting_start,
    )?;
    let step_sets = list("STEAM_STEPS", "1+5,1+5+10", steam::step_list)?;
    let n_folds = steam::env_number("STEAM_FOLDS", 3).max(2);
    let max_iter = steam::env_number("STEAM_MAX_ITER", 200);
    let threads = steam::env_number("STEAM_THREADS", 2).max(1);
    let steam::Halves { est, val } = steam::halves()?;
    let folds = steam::folds(&est, n_folds)?;
    let mut configs = Vec::new();
    for &(weighting, i) in &starts {
        for steps in &step_sets {
            configs.push(Config {
                weighting,
                i,
                steps: steps.clone(),
            });
        }
    }
    // Every (candidate, fold) pair is one job; the longest first.
    let mut jobs: Vec<(usize, usize)> = (0..configs.len())
        .flat_map(|c| (0..folds.len()).map(move |f| (c, f)))
        .collect();
    jobs.sort_by_key(|&(c, _)| std::cmp::Reverse(configs[c].settings(1).horizon));
    eprintln!(
        "{} candidates x {} folds, {threads} threads",
        configs.len(),
        folds.len()
    );
    let t = std::time::Instant::now();
    let done = in_threads(
        &jobs,
        threads,
        |&(c, f)| format!("  {} fold {f}", configs[c].label()),
        |&(c, f)| {
            let config = &configs[c];
            let fold = &folds[f];
            let start = config.start(&fold.est)?;
            let label = format!("  {} fold {f}", config.label());
            let r = timed_pem(&fold.est, &start, &config.settings(max_iter), &label)?;
            Ok((c, f, fits(&r.model, &fold.val)?))
        },
    )?;
    // A candidate's figures: the mean over its folds (all of them, or
    // NaN when a fold failed).
    let rows: Vec<(Config, Fits)> = configs
        .iter()
        .enumerate()
        .map(|(c, config)| {
            let mine: Vec<&Fits> = done
                .iter()
                .filter(|(cc, ..)| *cc == c)
                .map(|(_, _, f)| f)
                .collect();
            let mean = |g: fn(&Fits) -> f64| {
                if mine.len() == folds.len() {
                    mine.iter().map(|f| g(f)).sum::<f64>() / mine.len() as f64
                } else {
                    f64::NAN
                }
            };
            let fits = Fits {
                sim: mean(|f| f.sim),
                one: mean(|f| f.one),
                five: mean(|f| f.five),
            };
            (config.clone(), fits)
        })
        .collect();
    println!(
        "blocked cross-validation inside the estimation half ({} folds; max {max_iter} iterations; {:.0} s), mean over the folds:",
        folds.len(),
        t.elapsed().as_secs_f64()
    );
    println!("| candidate | simulation | 1-step | 5-step | score |\n|---|---|---|---|---|");
    let (score, chosen) = choose(
        &rows,
        |f| f,
        |c, f, score| {
            format!(
                "| {} | {:.2} | {:.2} | {:.2} | {score:.3} |",
                c.label(),
                f.sim,
                f.one,
                f.five
            )
        },
    )?;
    println!("chosen by the mean score ({score:.3}): {}", chosen.label());
    if !steam::refit() {
        return Ok(());
    }
    let t = std::time::Instant::now();
    let start = chosen.start(&est)?;
    table(
        &format!(
            "its N4SID start ({:?} i = {}, state regression)",
            chosen.weighting, chosen.i
        ),
        &start,
        &val,
    )?;
    steam::refit_and_validate(
        &est,
        &val,
        &start,
        &chosen.settings(max_iter),
        &chosen.label(),
        t,
    )?;
    Ok(())
}
