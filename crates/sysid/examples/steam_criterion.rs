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
use steam::{dynamics, fits, halves, inner_halves, table};

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

fn list<T>(var: &str, default: &str, parse: impl Fn(&str) -> Option<T>) -> Result<Vec<T>, String> {
    std::env::var(var)
        .unwrap_or_else(|_| default.into())
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| parse(s.trim()).ok_or(format!("{var}: cannot read {s:?}")))
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let criteria = list("STEAM_CRITERIA", "trace,fit", |s| match s {
        "trace" => Some(Criterion::Trace),
        "fit" => Some(Criterion::Fit),
        "det" => Some(Criterion::Determinant),
        _ => None,
    })?;
    let horizons = list("STEAM_HORIZONS", "1,6,10", |s| s.parse::<usize>().ok())?;
    let step_sets: Vec<Vec<usize>> = match std::env::var("STEAM_STEPS") {
        Ok(v) if !v.trim().is_empty() => list("STEAM_STEPS", "", |s| {
            s.split('+').map(|k| k.parse::<usize>().ok()).collect()
        })?,
        _ => Vec::new(),
    };
    let starts = list("STEAM_STARTS", "moesp:10", |s| {
        let (w, i) = s.split_once(':')?;
        let weighting = match w {
            "moesp" => Weighting::Moesp,
            "cva" => Weighting::Cva,
            "unweighted" => Weighting::Unweighted,
            _ => return None,
        };
        Some(Start {
            weighting,
            i: i.parse().ok()?,
        })
    })?;
    let refit = std::env::var("STEAM_REFIT").map_or(true, |v| v != "0");
    let steam::Halves { est, val } = halves()?;

    // Cross-validation inside the estimation half only.
    let steam::Halves {
        est: inner_est,
        val: inner_val,
    } = inner_halves(&est)?;
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
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    let Some((st, c, h, steps)) = jobs.get(i).cloned() else {
                        break;
                    };
                    // h = 1 with the one-step K refit is the same criterion twice.
                    let with_k: &[bool] = if h == 1 { &[false] } else { &[false, true] };
                    let r = fit(&inner_est, st, c, (h, &steps), with_k).and_then(|models| {
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
                    });
                    if let Ok(mut all) = results.lock() {
                        match r {
                            Ok(v) => all.extend(v),
                            Err(e) => eprintln!("  {st:?} {c:?} h = {h}: {e}"),
                        }
                    }
                }
            });
        }
    });
    let mut rows = results.into_inner().map_err(|_| "poisoned")?;
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
    let mut best: Option<(f64, Config)> = None;
    for (c, f) in &rows {
        let score = f.score();
        println!(
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
        );
        if score.is_finite() && best.as_ref().is_none_or(|(s, _)| score > *s) {
            best = Some((score, c.clone()));
        }
    }
    let (_, c) = best.ok_or("no configuration")?;
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
