//! The automatic structure choice of [`identify`](crate::workflow::identify()):
//! every dimension of the [`IdentifySpec`] that [`AutoSelect`] leaves free
//! (order, N4SID start, PEM focus and prediction horizon) is chosen by
//! blocked cross-validation inside the (prepared) estimation data only.
//!
//! The estimation data are cut into [`AutoSelect::folds`] consecutive
//! blocks (each experiment separately); every candidate is fitted on all
//! blocks but one (as separate experiments, their common means removed)
//! and scored on the held-out block. The score of a fold is the mean of
//! the mean k-step fits at the table's horizons and the mean simulation
//! fit clipped at 0 (a simulation worse than the mean counts as 0); a
//! candidate's score is its mean over the folds. The search is staged:
//! first the order (with the multi-step focus when the focus is free),
//! then focus and start at the chosen order. Jobs run on
//! [`AutoSelect::threads`] threads and no new job starts after
//! [`AutoSelect::time_budget`] seconds.

use super::choice::{Candidate, CandidateScore, SelectionReport};
use super::fit::fit_structure;
use super::spec::{AutoSelect, IdentifySpec, Method, PemFocus, Start};
use crate::data::{Experiment, IoData};
use crate::error::{Result, SysidError};
use crate::n4sid::MatrixEstimate;
use crate::validate::{compare, predict_fit};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// A fold: fit on `fit`, score on `held_out` (the same offsets removed).
struct Fold {
    fit: IoData,
    held_out: IoData,
}

/// Cuts every experiment of `est` into `k` consecutive blocks; fold `j`
/// holds out the `j`-th block of each.
/// A block longer than `max_block` samples keeps its first `max_block`
/// (the folds of a long record stay affordable; the blocks still spread
/// over the whole record).
fn folds(est: &IoData, k: usize, min_block: usize, max_block: usize) -> Result<Vec<Fold>> {
    let mut blocks: Vec<Vec<Experiment>> = vec![Vec::new(); k];
    for e in est.experiments() {
        let n = e.len();
        if n / k < min_block {
            continue;
        }
        for (j, block) in blocks.iter_mut().enumerate() {
            let a = j * n / k;
            let b = ((j + 1) * n / k).min(a + max_block.max(min_block));
            block.push(Experiment {
                t: e.t[a..b].to_vec(),
                u: e.u.rows(a, b - a).into_owned(),
                y: e.y.rows(a, b - a).into_owned(),
            });
        }
    }
    if blocks[0].is_empty() {
        return Err(SysidError::TooFewSamples {
            what: format!("{k}-fold cross-validation (blocks of {min_block} samples)"),
            needed: k * min_block,
            found: est.experiments().iter().map(|e| e.len()).max().unwrap_or(0),
        });
    }
    let mk = |x: Vec<Experiment>| {
        IoData::from_experiments(
            est.ts(),
            est.input_names().to_vec(),
            est.output_names().to_vec(),
            x,
        )
    };
    (0..k)
        .map(|j| {
            let others: Vec<Experiment> = (0..k)
                .filter(|&o| o != j)
                .flat_map(|o| blocks[o].iter().cloned())
                .collect();
            let (fit, off) = mk(others)?.remove_means()?;
            Ok(Fold {
                fit,
                held_out: mk(blocks[j].clone())?.subtract(&off)?,
            })
        })
        .collect()
}

/// The mean simulation fit and the mean k-step fits of the candidate
/// fitted on `fold.fit`, on `fold.held_out`.
fn score_fold(spec: &IdentifySpec, fold: &Fold) -> Result<Vec<f64>> {
    let fitted = fit_structure(&fold.fit, spec)?;
    let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let mut out = vec![mean(compare(&fitted.model, &fold.held_out)?.fit)];
    for &k in &spec.horizons {
        out.push(mean(predict_fit(&fitted.model, &fold.held_out, k)?));
    }
    Ok(out)
}

/// The score of the mean fits `[simulation, k-step...]`.
fn score(fits: &[f64]) -> f64 {
    let Some((sim, steps)) = fits.split_first() else {
        return f64::NEG_INFINITY;
    };
    let s = (steps.iter().sum::<f64>() + sim.max(0.0)) / fits.len() as f64;
    if s.is_finite() { s } else { f64::NEG_INFINITY }
}

/// Progress of the structure choice: `done` of `total` fits, and what
/// was fitted last.
#[derive(Clone, Debug, PartialEq)]
pub struct Progress {
    /// Fits done.
    pub done: usize,
    /// Fits planned so far.
    pub total: usize,
    /// What was fitted last.
    pub last: String,
}

/// A fold's figures: candidate, fold, the mean fits or why it failed.
type FoldResult = (usize, usize, std::result::Result<Vec<f64>, String>);

/// Shared state of one choice.
struct Search<'a> {
    spec: &'a IdentifySpec,
    auto: &'a AutoSelect,
    folds: Vec<Fold>,
    start: Instant,
    done: AtomicUsize,
    total: AtomicUsize,
    progress: &'a (dyn Fn(&Progress) + Sync),
    budget_hit: Mutex<bool>,
}

impl Search<'_> {
    /// Scores every candidate (on every fold, on the worker threads);
    /// a candidate whose folds did not all finish in time is left out.
    fn run(&self, candidates: &[Candidate]) -> Vec<CandidateScore> {
        let jobs: Vec<(usize, usize)> = (0..candidates.len())
            .flat_map(|c| (0..self.folds.len()).map(move |f| (c, f)))
            .collect();
        self.total.fetch_add(jobs.len(), Ordering::SeqCst);
        let next = AtomicUsize::new(0);
        let results: Mutex<Vec<FoldResult>> = Mutex::new(Vec::new());
        let threads = self.auto.threads.clamp(1, jobs.len().max(1));
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| {
                    loop {
                        if self.start.elapsed().as_secs_f64() > self.auto.time_budget {
                            if let Ok(mut b) = self.budget_hit.lock() {
                                *b = true;
                            }
                            break;
                        }
                        let i = next.fetch_add(1, Ordering::SeqCst);
                        let Some(&(c, f)) = jobs.get(i) else {
                            break;
                        };
                        let mut spec = candidates[c].apply(self.spec);
                        spec.max_iterations = spec.max_iterations.min(self.auto.fold_iterations);
                        let r = score_fold(&spec, &self.folds[f]).map_err(|e| e.to_string());
                        let done = self.done.fetch_add(1, Ordering::SeqCst) + 1;
                        (self.progress)(&Progress {
                            done,
                            total: self.total.load(Ordering::SeqCst),
                            last: format!("{} fold {}", candidates[c].label(), f + 1),
                        });
                        if let Ok(mut all) = results.lock() {
                            all.push((c, f, r));
                        }
                    }
                });
            }
        });
        let results = results.into_inner().unwrap_or_default();
        candidates
            .iter()
            .enumerate()
            .filter_map(|(c, cand)| {
                // In fold order, so the means do not depend on which
                // thread finished first.
                let mut mine: Vec<_> = results.iter().filter(|r| r.0 == c).collect();
                mine.sort_by_key(|r| r.1);
                if mine.len() < self.folds.len() {
                    return None;
                }
                if let Some((_, _, Err(e))) = mine.iter().find(|r| r.2.is_err()) {
                    return Some(CandidateScore {
                        candidate: cand.clone(),
                        fits: Vec::new(),
                        score: f64::NEG_INFINITY,
                        failed: Some(e.clone()),
                    });
                }
                let n = self.spec.horizons.len() + 1;
                let fits: Vec<f64> = (0..n)
                    .map(|j| {
                        mine.iter()
                            .filter_map(|r| r.2.as_ref().ok().map(|v| v[j]))
                            .sum::<f64>()
                            / mine.len() as f64
                    })
                    .collect();
                Some(CandidateScore {
                    candidate: cand.clone(),
                    score: score(&fits),
                    fits,
                    failed: None,
                })
            })
            .collect()
    }
}

/// The best finite score (the first of equal ones).
fn best(scores: &[CandidateScore]) -> Option<&CandidateScore> {
    scores.iter().filter(|s| s.score.is_finite()).fold(
        None,
        |b: Option<&CandidateScore>, s| match b {
            Some(b) if b.score >= s.score => Some(b),
            _ => Some(s),
        },
    )
}

/// Chooses the free dimensions of `spec` by blocked cross-validation on
/// the prepared estimation data `est`; returns the spec to fit and what
/// was chosen and why. `progress` is called after every fit.
pub(super) fn choose_structure(
    est: &IoData,
    spec: &IdentifySpec,
    auto: &AutoSelect,
    progress: &(dyn Fn(&Progress) + Sync),
) -> Result<(IdentifySpec, SelectionReport)> {
    if auto.folds < 2 {
        return Err(SysidError::invalid(format!(
            "the structure choice needs at least 2 folds, found {}",
            auto.folds
        )));
    }
    let free_order = auto.order && spec.order.is_none();
    let free_focus = auto.focus && spec.method == Method::Pem;
    let free_start = auto.start;
    let h = spec.horizons.iter().copied().max().unwrap_or(1).max(1);
    let base = Candidate::of_spec(spec);
    let multi = PemFocus::MultiStepThenNoise { horizon: h };
    let focus_first = if free_focus && h > 1 {
        Candidate {
            focus: multi,
            pem_horizon: 1,
            ..base.clone()
        }
    } else {
        base.clone()
    };
    let mut fixed = Vec::new();
    let mut free = Vec::new();
    let mut note = |on: bool, what: &str| {
        if on {
            free.push(what.to_string());
        } else {
            fixed.push(what.to_string());
        }
    };
    note(free_order, "order");
    note(free_start, "start");
    note(free_focus, "focus and prediction horizon");
    // Blocks long enough for the largest order's N4SID and PEM: at
    // least 20 samples per state and 50 in all; a short record lowers
    // the largest order tried.
    let longest = est.experiments().iter().map(|e| e.len()).max().unwrap_or(0);
    let fits_in = (longest / auto.folds.max(1) / 20).max(1);
    let max_order = auto.max_order.max(1).min(fits_in);
    let min_block = (20 * max_order).max(50);
    let search = Search {
        spec,
        auto,
        folds: folds(
            est,
            auto.folds,
            min_block,
            auto.max_fold_samples / (auto.folds * est.experiments().len()).max(1),
        )?,
        start: Instant::now(),
        done: AtomicUsize::new(0),
        total: AtomicUsize::new(0),
        progress,
        budget_hit: Mutex::new(false),
    };
    // Stage 1: the order, first on every other order (1, 2, 4, 6, 8 for
    // a largest order of 8), then the neighbours of the best.
    let of_order = |o: usize| Candidate {
        order: Some(o),
        ..focus_first.clone()
    };
    let mut stage1: Vec<Candidate> = if free_order {
        (1..=max_order)
            .filter(|&o| o == 1 || o % 2 == 0 || o == max_order)
            .map(of_order)
            .collect()
    } else {
        vec![focus_first.clone()]
    };
    let mut scores = search.run(&stage1);
    if free_order && let Some(Some(o)) = best(&scores).map(|b| b.candidate.order) {
        let near: Vec<Candidate> = [o.saturating_sub(1), o + 1]
            .into_iter()
            .filter(|&n| n >= 1 && n <= max_order)
            .map(of_order)
            .filter(|c| !stage1.contains(c))
            .collect();
        scores.extend(search.run(&near));
        stage1.extend(near);
    }
    let chosen = best(&scores).map_or(focus_first.clone(), |b| b.candidate.clone());
    // Stage 2: focus and start at that order.
    let mut stage2 = Vec::new();
    let foci: Vec<(PemFocus, usize)> = if free_focus {
        let mut v = vec![(PemFocus::Prediction, 1), (multi, 1)];
        if h > 1 {
            v.push((PemFocus::Prediction, h));
        }
        v
    } else {
        vec![(chosen.focus, chosen.pem_horizon)]
    };
    let starts: Vec<(Start, MatrixEstimate, bool)> = if free_start {
        // A feed-through is the user's statement about the plant, never
        // chosen here: in closed loop `D` learns the controller's
        // reaction within the sample (the logged input is computed from
        // the same sample's output), which predicts well and is no
        // plant model.
        vec![
            (Start::N4sid, MatrixEstimate::OutputError, spec.feedthrough),
            (Start::Pbsid, MatrixEstimate::OutputError, spec.feedthrough),
            (
                Start::N4sid,
                MatrixEstimate::StateRegression,
                spec.feedthrough,
            ),
        ]
    } else {
        vec![(chosen.start, chosen.n4sid_matrices, chosen.feedthrough)]
    };
    // The chosen focus with the other starts first (what the budget
    // leaves out comes last).
    let mut foci = foci;
    if let Some(i) = foci
        .iter()
        .position(|&f| f == (chosen.focus, chosen.pem_horizon))
    {
        let f = foci.remove(i);
        foci.insert(0, f);
    }
    for &(focus, pem_horizon) in &foci {
        for &(start, n4sid_matrices, feedthrough) in &starts {
            let c = Candidate {
                start,
                focus,
                pem_horizon,
                n4sid_matrices,
                feedthrough,
                ..chosen.clone()
            };
            if !stage1.contains(&c) {
                stage2.push(c);
            }
        }
    }
    scores.extend(search.run(&stage2));
    let budget_hit = search.budget_hit.lock().map(|b| *b).unwrap_or(false);
    let Some(winner) = best(&scores).cloned() else {
        if budget_hit {
            // Nothing finished in time: the first candidate, unscored.
            let report = SelectionReport {
                folds: auto.folds,
                horizons: spec.horizons.clone(),
                free,
                fixed,
                chosen: focus_first.clone(),
                score: f64::NAN,
                candidates: scores,
                seconds: search.start.elapsed().as_secs_f64(),
                budget_hit,
            };
            return Ok((focus_first.apply(spec), report));
        }
        let why = scores
            .iter()
            .find_map(|s| s.failed.clone())
            .unwrap_or_else(|| "no candidate".into());
        if why.starts_with("too few samples") {
            return Err(SysidError::TooFewSamples {
                what: format!("the structure choice ({why})"),
                needed: 0,
                found: est.n_samples(),
            });
        }
        return Err(SysidError::invalid(format!(
            "the structure choice found no usable candidate: {why}"
        )));
    };
    let report = SelectionReport {
        folds: auto.folds,
        horizons: spec.horizons.clone(),
        free,
        fixed,
        chosen: winner.candidate.clone(),
        score: winner.score,
        candidates: scores,
        seconds: search.start.elapsed().as_secs_f64(),
        budget_hit,
    };
    Ok((winner.candidate.apply(spec), report))
}
