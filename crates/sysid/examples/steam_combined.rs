//! The DaISy steam generator with a criterion of the validation score's
//! own shape: the simulation error (`K = 0`, its own initial state)
//! together with the 1-step and 5-step prediction errors of the same
//! model in one objective ([`PemSettings::simulation_weight`] next to
//! [`PemSettings::steps`] `[1, 5]`). With [`Criterion::Fit`] and weight 1
//! the criterion is the sum over outputs of the RMS simulation, 1-step
//! and 5-step errors of the outputs scaled to unit variance: up to the
//! normalisation, minus the sum of the three mean fits the tables report.
//!
//! The start (N4SID MOESP `i = 20`, or the 1..6-step fit-criterion PEM
//! model from it), the criterion and the simulation weight are chosen by
//! cross-validation inside the estimation half (fit on its first 2/3,
//! score on its last 1/3; score: the sum of the mean simulation, 1-step
//! and 5-step fits); the chosen configuration is then fitted on the whole
//! estimation half and validated once on the second half:
//!
//! `cargo run --release -p kestrel-sysid --example steam_combined [path]`
//!
//! `STEAM_STARTS` (`n4sid`, `warm`; default both), `STEAM_CRITERIA`
//! (default `fit,trace`), `STEAM_STEPS` (default `1+5`), `STEAM_WEIGHTS`
//! (default `0,0.25,1`) set the grid (12 candidates by default, about 8
//! minutes on 2 loaded cores); `STEAM_REFIT=0` stops after the
//! inner table; `STEAM_VALIDATE_ALL=1` also refits and validates every
//! candidate after the choice, for information (not a way to choose).
//! The inner table also shows the simulation fit on the
//! fitted 2/3 itself (not part of the score), to tell a criterion that
//! does not reach a better simulation from one whose gain does not carry
//! over to new data.

#[path = "common/steam.rs"]
mod steam;

use kestrel_sysid::{Criterion, InnovationModel, IoData, N4sidSettings, PemSettings, Weighting};
use steam::{choose, criterion, dynamics, fits, in_threads, list, timed_pem};

/// Where the combined fit starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Start {
    /// N4SID MOESP `i = 20`, order 9.
    N4sid,
    /// The 1..6-step PEM with the fit criterion from that N4SID model
    /// (the README's best 5-step model).
    Warm,
}

/// A candidate of the grid.
#[derive(Clone, Debug)]
struct Config {
    start: Start,
    criterion: Criterion,
    steps: Vec<usize>,
    weight: f64,
}

impl Config {
    fn settings(&self) -> PemSettings {
        PemSettings {
            criterion: self.criterion,
            horizon: self.steps.iter().copied().max().unwrap_or(1),
            steps: self.steps.clone(),
            simulation_weight: self.weight,
            ..Default::default()
        }
    }
}

/// N4SID MOESP `i = 20` of order 9 on `est`.
fn n4sid_start() -> N4sidSettings {
    N4sidSettings {
        weighting: Weighting::Moesp,
        horizon: Some(20),
        ..Default::default()
    }
}

/// The start models of `est`: the N4SID model and, if asked for, the
/// 1..6-step fit-criterion PEM model from it.
fn starts(est: &IoData, which: &[Start]) -> Result<Vec<(Start, InnovationModel)>, String> {
    let mut out = Vec::new();
    let st = kestrel_sysid::n4sid(
        est,
        &N4sidSettings {
            order: Some(steam::ORDER),
            ..n4sid_start()
        },
    )
    .map_err(|e| e.to_string())?;
    if which.contains(&Start::N4sid) {
        out.push((Start::N4sid, st.model.clone()));
    }
    if which.contains(&Start::Warm) {
        let warm = dynamics(
            est,
            n4sid_start(),
            &PemSettings {
                criterion: Criterion::Fit,
                horizon: 6,
                ..Default::default()
            },
            "  warm start: fit criterion, 1..6 steps",
        )?;
        out.push((Start::Warm, warm.model));
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let which = list("STEAM_STARTS", "n4sid,warm", |s| match s {
        "n4sid" => Some(Start::N4sid),
        "warm" => Some(Start::Warm),
        _ => None,
    })?;
    let criteria = list("STEAM_CRITERIA", "fit,trace", criterion)?;
    let step_sets: Vec<Vec<usize>> = list("STEAM_STEPS", "1+5", |s| {
        s.split('+').map(|k| k.parse::<usize>().ok()).collect()
    })?;
    let weights = list("STEAM_WEIGHTS", "0,0.25,1", |s| s.parse::<f64>().ok())?;
    let refit = steam::refit();
    // Cross-validation inside the estimation half only.
    let steam::Split {
        est,
        val,
        inner_est,
        inner_val,
    } = steam::split()?;
    let t = std::time::Instant::now();
    let inner_starts = starts(&inner_est, &which)?;
    let mut jobs: Vec<(Config, &InnovationModel)> = Vec::new();
    for (st, model) in &inner_starts {
        for &criterion in &criteria {
            for steps in &step_sets {
                for &weight in &weights {
                    let c = Config {
                        start: *st,
                        criterion,
                        steps: steps.clone(),
                        weight,
                    };
                    jobs.push((c, model));
                }
            }
        }
    }
    // Two worker threads take the jobs in turn.
    let mut rows = in_threads(
        &jobs,
        2,
        |(c, _)| format!("  {c:?}"),
        |(c, start)| {
            let r = timed_pem(&inner_est, start, &c.settings(), &format!("  {c:?}"))?;
            let f = (fits(&r.model, &inner_val)?, fits(&r.model, &inner_est)?);
            Ok((c.clone(), f))
        },
    )?;
    rows.sort_by(|(a, _), (b, _)| {
        (format!("{:?}{:?}{:?}", a.start, a.criterion, a.steps))
            .cmp(&format!("{:?}{:?}{:?}", b.start, b.criterion, b.steps))
            .then(a.weight.total_cmp(&b.weight))
    });
    println!(
        "cross-validation inside the estimation half (fit on 2/3, score on 1/3; {:.0} s):",
        t.elapsed().as_secs_f64()
    );
    println!(
        "| start | criterion | steps | simulation weight | simulation | 1-step | 5-step | score | simulation on the fitted 2/3 |\n|---|---|---|---|---|---|---|---|---|"
    );
    let (_, c) = choose(
        &rows,
        |(f, _)| f,
        |c, (f, fe), score| {
            format!(
                "| {:?} | {:?} | {:?} | {} | {:.2} | {:.2} | {:.2} | {score:.2} | {:.2} |",
                c.start, c.criterion, c.steps, c.weight, f.sim, f.one, f.five, fe.sim
            )
        },
    )?;
    println!("chosen by the inner score: {c:?}");
    if !refit {
        return Ok(());
    }

    // The chosen configuration on the whole estimation half, validated once.
    let t = std::time::Instant::now();
    let (_, start) = starts(&est, &[c.start])?.pop().ok_or("no start model")?;
    steam::refit_and_validate(&est, &val, &start, &c.settings(), &format!("{c:?}"), t)?;
    if std::env::var("STEAM_VALIDATE_ALL").is_ok_and(|v| v == "1") {
        // For information only: what the other candidates would have
        // given. Looking at these is not a way to choose.
        println!("every candidate refitted and validated (for information, NOT a choice):");
        println!(
            "| start | criterion | steps | simulation weight | simulation | 1-step | 5-step | simulation on the estimation half |\n|---|---|---|---|---|---|---|---|"
        );
        let all_starts = starts(&est, &which)?;
        for (o, _) in &rows {
            let Some((_, start)) = all_starts.iter().find(|(s, _)| *s == o.start) else {
                continue;
            };
            let r = timed_pem(&est, start, &o.settings(), &format!("refit {o:?}"))?;
            let (f, fe) = (fits(&r.model, &val)?, fits(&r.model, &est)?);
            println!(
                "| {:?} | {:?} | {:?} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
                o.start, o.criterion, o.steps, o.weight, f.sim, f.one, f.five, fe.sim
            );
        }
    }
    Ok(())
}
