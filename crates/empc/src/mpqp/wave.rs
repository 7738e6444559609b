//! One wave of the exploration: the neighbour active sets and probe
//! points of the last regions found, processed on several threads with
//! the `parallel` feature, each active set's region computed once.
//!
//! A wave runs in three parallel phases: the regions of the guessed
//! neighbour sets (with the probe points those regions do not contain),
//! the QP at every probe point (its candidate active sets), then the
//! regions of the candidate sets no earlier wave or phase has computed.
//! The results are then replayed in the order of the work items, as if
//! each item had been processed on its own from start to end (its set's
//! region, then its probes' regions), so the regions come out in the
//! same order whatever the number of threads, and in the order of the
//! former one-phase wave (which recomputed a set's region each time a
//! probe met it again; `region` is deterministic, so the results are the
//! same).

use crate::error::EmpcError;
use crate::lp::LpWorkspace;
use crate::mpqp::prepare::Prepared;
use crate::mpqp::region::RegionData;
use crate::mpqp::settings::Settings;
use std::collections::HashMap;

/// A probe point beyond a facet.
#[derive(Clone, Debug)]
pub(super) struct Witness {
    pub(super) theta: Vec<f64>,
    pub(super) facet_a: Vec<f64>,
    pub(super) facet_b: f64,
}

/// A work item of a wave.
pub(super) enum Work {
    /// A guessed neighbour active set, with the probe points beyond the
    /// facets that led to it (each must lie in its region).
    Set(Vec<usize>, Vec<Witness>),
    /// A probe point whose neighbour could not be guessed.
    Probe(Witness),
}

/// What the exploration learns from a wave, in the order of the work items.
pub(super) enum Event {
    /// A full-dimensional region (possibly one already known: the caller
    /// skips duplicates).
    Region(RegionData),
    /// A guessed active set without a full-dimensional region.
    NoRegion(Vec<usize>),
    /// A facet beyond which the QP is infeasible (a boundary of the
    /// explored set).
    Hull(Vec<f64>, f64),
}

/// The events and counters of a wave.
#[derive(Default)]
pub(super) struct WaveOut {
    pub(super) events: Vec<Event>,
    /// Regions computed (active sets tested).
    pub(super) tested: usize,
    /// Guessed sets without a region.
    pub(super) discarded: usize,
    /// Probe points (QPs solved).
    pub(super) fallbacks: usize,
    /// LPs of the regions computed.
    pub(super) lps: usize,
}

/// `f` over `items`, on rayon's threads when allowed.
fn map<T: Sync, U: Send>(
    items: &[T],
    settings: &Settings,
    lp: &mut LpWorkspace,
    f: impl Fn(&T, &mut LpWorkspace) -> U + Sync,
) -> Vec<U> {
    #[cfg(feature = "parallel")]
    if settings.parallel && items.len() > 1 {
        use rayon::prelude::*;
        return items
            .par_iter()
            .map_init(LpWorkspace::default, |lp, t| f(t, lp))
            .collect();
    }
    #[cfg(not(feature = "parallel"))]
    let _ = settings;
    items.iter().map(|t| f(t, lp)).collect()
}

/// Runs a wave. `status` holds every active set tested in earlier waves
/// (`Some`: its region's index; `None`: no full-dimensional region); the
/// regions of those sets are not computed again.
pub(super) fn run_wave(
    prep: &Prepared,
    items: &[Work],
    settings: &Settings,
    status: &HashMap<Vec<usize>, Option<usize>>,
    lp: &mut LpWorkspace,
) -> Result<WaveOut, EmpcError> {
    let mut out = WaveOut::default();
    let tol_in = 1e-9 * prep.scale;
    // Phase 1: the guessed sets.
    let guessed: Vec<&[usize]> = items
        .iter()
        .filter_map(|w| match w {
            Work::Set(act, _) => Some(act.as_slice()),
            Work::Probe(_) => None,
        })
        .collect();
    let mut first: Vec<Option<RegionData>> =
        map(&guessed, settings, lp, |act, lp| prep.region(act, lp));
    // The probes, in item order: the witnesses a set's region does not
    // contain (all of them without a region), then the item's own probe.
    let mut probes: Vec<&[f64]> = Vec::new();
    let mut probe_facets: Vec<(&[f64], f64)> = Vec::new();
    // Per item: the index of its guessed set (if any) and its probes' range.
    let mut plan: Vec<(Option<usize>, std::ops::Range<usize>)> = Vec::with_capacity(items.len());
    let mut k = 0;
    for w in items {
        let start = probes.len();
        let set = match w {
            Work::Set(_, wits) => {
                let r = first[k].as_ref();
                for wit in wits {
                    if r.is_none_or(|r| !r.contains(&wit.theta, tol_in)) {
                        probes.push(&wit.theta);
                        probe_facets.push((&wit.facet_a, wit.facet_b));
                    }
                }
                k += 1;
                Some(k - 1)
            }
            Work::Probe(wit) => {
                probes.push(&wit.theta);
                probe_facets.push((&wit.facet_a, wit.facet_b));
                None
            }
        };
        plan.push((set, start..probes.len()));
    }
    // Phase 2: the QP at every probe point.
    let max_set = settings.max_degenerate_set;
    let candidates = map(&probes, settings, lp, |theta, lp| {
        prep.sets_at(theta, max_set, lp)
    });
    let candidates = candidates.into_iter().collect::<Result<Vec<_>, _>>()?;
    // Phase 3: the regions of candidate sets nobody has computed.
    let mut known: HashMap<&[usize], usize> = HashMap::new();
    for (i, act) in guessed.iter().enumerate() {
        known.entry(act).or_insert(i);
    }
    let mut todo: Vec<&[usize]> = Vec::new();
    let mut todo_idx: HashMap<&[usize], usize> = HashMap::new();
    for sets in candidates.iter().flatten() {
        for s in sets {
            let s = s.as_slice();
            if !status.contains_key(s) && !known.contains_key(s) && !todo_idx.contains_key(s) {
                todo_idx.insert(s, todo.len());
                todo.push(s);
            }
        }
    }
    let mut second: Vec<Option<RegionData>> =
        map(&todo, settings, lp, |act, lp| prep.region(act, lp));
    out.tested = guessed.len() + todo.len();
    out.fallbacks = probes.len();
    out.lps = first.iter().chain(&second).flatten().map(|r| r.lps).sum();
    let has_region: Vec<bool> = first.iter().map(Option::is_some).collect();
    // Replay in item order. A set met again takes nothing: its region was
    // handed out at its first meeting (or it has none).
    for (set, range) in plan {
        if let Some(i) = set {
            if let Some(r) = first[i].take() {
                out.events.push(Event::Region(r));
            } else if !has_region[i] {
                out.discarded += 1;
                out.events.push(Event::NoRegion(guessed[i].to_vec()));
            }
        }
        for p in range {
            let Some(sets) = &candidates[p] else {
                let (a, b) = probe_facets[p];
                out.events.push(Event::Hull(a.to_vec(), b));
                continue;
            };
            for s in sets {
                let s = s.as_slice();
                let slot = match (known.get(s), todo_idx.get(s)) {
                    (Some(&i), _) => &mut first[i],
                    (None, Some(&i)) => &mut second[i],
                    (None, None) => continue, // tested in an earlier wave
                };
                if let Some(r) = slot.take() {
                    out.events.push(Event::Region(r));
                }
            }
        }
    }
    Ok(out)
}
