//! The DaISy steam generator: the PEM criterion ([`Criterion::Trace`]
//! or [`Criterion::Fit`], the sum of the RMS errors per output and step)
//! and the multi-step horizon `h`, each with the noise model `K` of the
//! fit kept or re-estimated by one-step prediction with the dynamics
//! fixed, chosen by cross-validation inside the estimation half (fit on
//! its first 2/3, score on its last 1/3; score: the sum of the mean
//! simulation, 1-step and 5-step fits). The chosen configuration is then
//! fitted on the whole estimation half and validated once on the second
//! half:
//!
//! `cargo run --release -p kestrel-sysid --example steam_criterion [path]`
//!
//! `STEAM_STARTS` (N4SID starts `weighting:i`, default `moesp:10`),
//! `STEAM_CRITERIA` (default `trace,fit`), `STEAM_HORIZONS` (default
//! `1,6,10`: all steps `1..=h`) and `STEAM_STEPS` (selected step sets
//! such as `1+5,1+5+10`, [`PemSettings::steps`]; default none) set the grid; `STEAM_REFIT=0` stops after the inner table.

#[path = "common/steam.rs"]
mod steam;

use kestrel_sysid::{
    Criterion, InnovationModel, IoData, N4sidSettings, PemSettings, Weighting, pem,
};
use steam::{Fits, choose, criterion, dynamics, fits, in_threads, list, table};

/// The N4SID start: weighting and horizon (block rows).
#[derive(Clone, Copy, Debug)]
struct Start {
    weighting: Weighting,
    i: usize,
}

/// A candidate: N4SID start, criterion, dynamics horizon, and whether `K`
/// is re-estimated by one-step prediction afterwards.
#[derive(Clone, Debug)]
struct Config {
    start: Start,
    criterion: Criterion,
    h: usize,
    /// Selected steps (empty: all of `1..=h`).
    steps: Vec<usize>,
    refit_k: bool,
}

/// The dynamics fit and, for `with_k`, the `K` refit: `(refit_k, model)`.
fn fit(
    est: &IoData,
    st: Start,
    criterion: Criterion,
    (h, steps): (usize, &[usize]),
    with_k: &[bool],
) -> Result<Vec<(bool, InnovationModel)>, String> {
    let dynamics = dynamics(
        est,
        N4sidSettings {
            weighting: st.weighting,
            horizon: Some(st.i),
            ..Default::default()
        },
        &PemSettings {
            horizon: h,
            steps: steps.to_vec(),
            criterion,
            ..Default::default()
        },
        &format!("  {st:?} {criterion:?} h = {h} steps {steps:?}"),
    )?;
    let mut out = Vec::new();
    for &refit in with_k {
        if !refit {
            out.push((false, dynamics.model.clone()));
            continue;
        }
        let k = pem(
            est,
            &dynamics.model,
            &PemSettings {
                fixed_dynamics: true,
                criterion,
                ..Default::default()
            },
        )
        .map_err(|e| e.to_string())?;
        out.push((true, k.model));
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let criteria = list("STEAM_CRITERIA", "trace,fit", |s| {
        criterion(s).or((s == "det").then_some(Criterion::Determinant))
    })?;
    let horizons = list("STEAM_HORIZONS", "1,6,10", |s| s.parse::<usize>().ok())?;
    let step_sets: Vec<Vec<usize>> = match std::env::var("STEAM_STEPS") {
        Ok(v) if !v.trim().is_empty() => list("STEAM_STEPS", "", |s| {
            s.split('+').map(|k| k.parse::<usize>().ok()).collect()
        })?,
        _ => Vec::new(),
    };
    let starts = list("STEAM_STARTS", "moesp:10", |s| {
        let (weighting, i) = steam::weighting_start(s)?;
        Some(Start { weighting, i })
    })?;
    let refit = steam::refit();
    // Cross-validation inside the estimation half only.
    let steam::Split {
        est,
        val,
        inner_est,
        inner_val,
    } = steam::split()?;
    let mut jobs: Vec<(Start, Criterion, usize, Vec<usize>)> = Vec::new();
    for &st in &starts {
        for &c in &criteria {
            for &h in &horizons {
                jobs.push((st, c, h, Vec::new()));
            }
            for set in &step_sets {
                let h = set.iter().copied().max().unwrap_or(1);
                jobs.push((st, c, h, set.clone()));
            }
        }
    }
    // Two worker threads take the jobs in turn.
    let results = in_threads(
        &jobs,
        2,
        |(st, c, h, _)| format!("  {st:?} {c:?} h = {h}"),
        |&(st, c, h, ref steps)| {
            // h = 1 with the one-step K refit is the same criterion twice.
            let with_k: &[bool] = if h == 1 { &[false] } else { &[false, true] };
            fit(&inner_est, st, c, (h, steps), with_k).and_then(|models| {
                models
                    .into_iter()
                    .map(|(k, m)| {
                        let f = fits(&m, &inner_val)?;
                        Ok((
                            Config {
                                start: st,
                                criterion: c,
                                h,
                                steps: steps.clone(),
                                refit_k: k,
                            },
                            f,
                        ))
                    })
                    .collect::<Result<Vec<_>, String>>()
            })
        },
    )?;
    let mut rows: Vec<(Config, Fits)> = results.into_iter().flatten().collect();
    rows.sort_by_key(|(c, _)| {
        (
            format!("{:?}{:?}", c.start, c.criterion),
            c.h,
            c.steps.clone(),
            c.refit_k,
        )
    });
    println!("cross-validation inside the estimation half (fit on 2/3, score on 1/3):");
    println!(
        "| start | criterion | steps | K | simulation | 1-step | 5-step | score |\n|---|---|---|---|---|---|---|---|"
    );
    let (_, c) = choose(
        &rows,
        |f| f,
        |c, f, score| {
            format!(
                "| {:?} i = {} | {:?} | {} | {} | {:.2} | {:.2} | {:.2} | {score:.2} |",
                c.start.weighting,
                c.start.i,
                c.criterion,
                if c.steps.is_empty() {
                    format!("1..{}", c.h)
                } else {
                    format!("{:?}", c.steps)
                },
                if c.refit_k { "one-step" } else { "kept" },
                f.sim,
                f.one,
                f.five
            )
        },
    )?;
    println!("chosen by the inner score: {c:?}");
    if !refit {
        return Ok(());
    }

    // The chosen configuration on the whole estimation half, validated once.
    let t = std::time::Instant::now();
    let models = fit(&est, c.start, c.criterion, (c.h, &c.steps), &[c.refit_k])?;
    let (_, model) = models.last().ok_or("no model")?;
    table(
        &format!("{c:?} ({:.1} s)", t.elapsed().as_secs_f64()),
        model,
        &val,
    )?;
    Ok(())
}
