//! The DaISy steam generator, with every PEM search run to convergence:
//! the cross-validated choice of `steam_criterion`/`steam_combined`
//! redone with [`PemSettings::max_iterations`] raised from the default 30
//! to 200 (default tolerances), so that the compared candidates are
//! minimisers of their own criteria rather than searches cut off
//! half-way. Every inner fit and the refit report their iterations and
//! stop reason.
//!
//! Candidates: the N4SID start (MOESP `i = 10` or `i = 20`, order 9),
//! the criterion ([`Criterion::Trace`] or [`Criterion::Fit`]), the
//! prediction steps (`1..5`, `1..6`, `1..10`: all of `1..=h`; `1+5`: the
//! 1- and 5-step errors only, `h = 5`) and the simulation weight (0 for
//! every step set, and 0.25 for the step sets in `STEAM_WEIGHTED_STEPS`),
//! `K` kept. The
//! choice is made by cross-validation inside the estimation half (fit on
//! its first 2/3, score on its last 1/3; score: the sum of the mean
//! simulation, 1-step and 5-step fits); the chosen configuration is then
//! fitted on the whole estimation half (to convergence too) and validated
//! once on the second half:
//!
//! `cargo run --release -p kestrel-sysid --example steam_converged [path]`
//!
//! `STEAM_STARTS` (default `moesp:10,moesp:20`), `STEAM_CRITERIA`
//! (default `trace,fit`), `STEAM_STEPS` (default `1..5,1..6,1..10,1+5`;
//! `1..h`: all steps up to `h`, `a+b+...`: selected steps),
//! `STEAM_WEIGHTS` (positive simulation weights, default `0.25`),
//! `STEAM_WEIGHTED_STEPS` (the step sets that also get the positive
//! weights, default `1+5`), `STEAM_MAX_ITER` (default 200) and
//! `STEAM_THREADS` (default 2) set the grid (20 candidates by default,
//! about 10 minutes on 2 cores, 21 when they are loaded);
//! `STEAM_REFIT=0` stops after the inner table.

#[path = "common/steam.rs"]
mod steam;

use kestrel_sysid::{Criterion, InnovationModel, IoData, N4sidSettings, PemSettings, Weighting};
use steam::{choose, criterion, fits, in_threads, list, timed_pem};

/// A step set: all of `1..=h` (`steps` empty) or the selected steps.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Steps {
    h: usize,
    steps: Vec<usize>,
    /// As written in `STEAM_STEPS`.
    name: String,
}

/// A candidate of the grid.
#[derive(Clone, Debug)]
struct Config {
    /// N4SID MOESP block rows `i`.
    i: usize,
    criterion: Criterion,
    steps: Steps,
    weight: f64,
}

impl Config {
    fn settings(&self, max_iterations: usize) -> PemSettings {
        PemSettings {
            criterion: self.criterion,
            horizon: self.steps.h,
            steps: self.steps.steps.clone(),
            simulation_weight: self.weight,
            max_iterations,
            ..Default::default()
        }
    }

    /// About how much work a fit is (for handing out the longest first).
    fn work(&self) -> f64 {
        self.steps.h as f64 + if self.weight > 0.0 { 1.5 } else { 0.0 }
    }

    fn label(&self) -> String {
        format!(
            "MOESP i = {} | {:?} | {} | {}",
            self.i, self.criterion, self.steps.name, self.weight
        )
    }
}

/// N4SID MOESP with `i` block rows, order 9, on `est`.
fn start(est: &IoData, i: usize) -> Result<InnovationModel, String> {
    kestrel_sysid::n4sid(
        est,
        &N4sidSettings {
            weighting: Weighting::Moesp,
            horizon: Some(i),
            order: Some(steam::ORDER),
            ..Default::default()
        },
    )
    .map(|r| r.model)
    .map_err(|e| e.to_string())
}

fn parse_steps(s: &str) -> Option<Steps> {
    if let Some(h) = s.strip_prefix("1..") {
        let h = h.parse::<usize>().ok().filter(|&h| h > 0)?;
        return Some(Steps {
            h,
            steps: Vec::new(),
            name: s.into(),
        });
    }
    let steps = steam::step_list(s)?;
    Some(Steps {
        h: steps.iter().copied().max()?,
        steps,
        name: s.into(),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let starts = list("STEAM_STARTS", "moesp:10,moesp:20", |s| {
        s.strip_prefix("moesp:")?.parse::<usize>().ok()
    })?;
    let criteria = list("STEAM_CRITERIA", "trace,fit", criterion)?;
    let step_sets = list("STEAM_STEPS", "1..5,1..6,1..10,1+5", parse_steps)?;
    let weights = list("STEAM_WEIGHTS", "0.25", |s| {
        s.parse::<f64>().ok().filter(|w| *w > 0.0)
    })?;
    let weighted = list("STEAM_WEIGHTED_STEPS", "1+5", parse_steps)?;
    let max_iter = steam::env_number("STEAM_MAX_ITER", 200);
    let threads = steam::env_number("STEAM_THREADS", 2).max(1);
    let refit = steam::refit();
    // Cross-validation inside the estimation half only.
    let steam::Split {
        est,
        val,
        inner_est,
        inner_val,
    } = steam::split()?;
    let t = std::time::Instant::now();
    let inner_starts: Vec<(usize, InnovationModel)> = starts
        .iter()
        .map(|&i| start(&inner_est, i).map(|m| (i, m)))
        .collect::<Result<_, _>>()?;
    let mut jobs: Vec<(Config, &InnovationModel)> = Vec::new();
    for (i, model) in &inner_starts {
        for &criterion in &criteria {
            for steps in &step_sets {
                let mut ws = vec![0.0];
                if weighted
                    .iter()
                    .any(|w| w.h == steps.h && w.steps == steps.steps)
                {
                    ws.extend(&weights);
                }
                for weight in ws {
                    let c = Config {
                        i: *i,
                        criterion,
                        steps: steps.clone(),
                        weight,
                    };
                    jobs.push((c, model));
                }
            }
        }
    }
    // The longest fits first, so that the workers finish together.
    jobs.sort_by(|(a, _), (b, _)| b.work().total_cmp(&a.work()));
    eprintln!("{} candidates, {threads} threads", jobs.len());
    let mut rows = in_threads(
        &jobs,
        threads,
        |(c, _)| format!("  {}", c.label()),
        |(c, start)| {
            let t = std::time::Instant::now();
            let label = format!("  {}", c.label());
            let r = timed_pem(&inner_est, start, &c.settings(max_iter), &label)?;
            let f = (
                fits(&r.model, &inner_val)?,
                fits(&r.model, &inner_est)?,
                r.iterations,
                r.stop,
                t.elapsed().as_secs_f64(),
            );
            Ok((c.clone(), f))
        },
    )?;
    rows.sort_by_key(|(c, _)| c.label());
    println!(
        "cross-validation inside the estimation half (fit on 2/3, score on 1/3; max {max_iter} iterations; {:.0} s):",
        t.elapsed().as_secs_f64()
    );
    println!(
        "| start | criterion | steps | simulation weight | iterations | stop | time (s) | simulation | 1-step | 5-step | score | simulation on the fitted 2/3 |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    let (score, c) = choose(
        &rows,
        |(f, ..)| f,
        |c, (f, fe, its, stop, secs), score| {
            format!(
                "| {} | {its} | {stop:?} | {secs:.0} | {:.2} | {:.2} | {:.2} | {score:.3} | {:.2} |",
                c.label(),
                f.sim,
                f.one,
                f.five,
                fe.sim
            )
        },
    )?;
    println!("chosen by the inner score ({score:.3}): {}", c.label());
    if !refit {
        return Ok(());
    }

    // The chosen configuration on the whole estimation half, to
    // convergence, validated once.
    let t = std::time::Instant::now();
    let st = start(&est, c.i)?;
    steam::refit_and_validate(&est, &val, &st, &c.settings(max_iter), &c.label(), t)?;
    Ok(())
}
