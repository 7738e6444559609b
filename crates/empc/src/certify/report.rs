//! The certificate: worst cases, their regions in parameter units, the
//! summary counts, and the regions themselves for look-ups.

use super::explore::{Leaf, Tally, Worst, path_text};
use super::model::{Model, UPPER};
use super::step::{Change, Status};
use kestrel_qp::parametric::ParametricQp;
use kestrel_qp::{ActiveConstraint, Side};
use serde_json::{Value, json};
use std::fmt;
use std::time::Duration;

/// The cold-start certificate and, if asked for, the warm-start one.
#[derive(Debug, Clone)]
pub struct Certification {
    /// From the empty active set.
    pub cold: Certificate,
    /// From the previous period's optimal active set (sorted by
    /// constraint index) over the stated step.
    pub warm: Option<Certificate>,
}

/// One region of the partition, reported in parameter units.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionReport {
    /// Active-set changes the solver makes on it.
    pub iterations: usize,
    /// Floating-point operations of the solve (docs/qp-certify.md's model).
    pub flops: u64,
    /// How the solve ends.
    pub status: Status,
    /// An interior point (the centre of the largest inscribed ball).
    pub theta: Vec<f64>,
    /// Warm start: the previous parameter of that point.
    pub theta_prev: Option<Vec<f64>>,
    /// The ball's radius in the box normalised to `[-1, 1]^p`.
    pub radius: f64,
    /// The region `a' x <= b` with `x = theta` (cold) or `x = (theta,
    /// theta_prev)` (warm), in parameter units.
    pub halfspaces: Vec<(Vec<f64>, f64)>,
    /// The active-set changes, in order.
    pub path: Vec<Change>,
    /// Warm start: the set the solver started from, in its stored order
    /// (sorted by index unless certified for any order).
    pub start_set: Vec<ActiveConstraint>,
}

/// The certified complexity of one start (cold or warm).
#[derive(Debug, Clone)]
pub struct Certificate {
    /// `None` for the cold start; the warm step (fraction of each
    /// parameter's box width) otherwise.
    pub warm_step: Option<f64>,
    /// Whether the partition is exact: every decision was split by its
    /// own affine half-spaces, none over-approximated (regions thinner
    /// than `min_radius` and tolerance slivers of the solver's own
    /// comparisons excepted). The counts are then attained, not bounds.
    pub exact: bool,
    /// Variables, solver rows (general rows of `G`), parameters.
    pub n: usize,
    /// See [`Self::n`].
    pub m: usize,
    /// See [`Self::n`].
    pub p: usize,
    /// The most iterations on any region.
    pub worst_iterations: usize,
    /// The most flops on any region.
    pub worst_flops: u64,
    /// A region with [`Self::worst_iterations`] (the one with the largest
    /// inscribed ball).
    pub worst: Option<RegionReport>,
    /// A region with [`Self::worst_flops`].
    pub worst_flops_region: Option<RegionReport>,
    /// Regions of the partition.
    pub regions: usize,
    /// Regions by iteration count (`histogram[i]` regions take `i`).
    pub histogram: Vec<usize>,
    /// Regions where the solver reports infeasibility.
    pub infeasible_regions: usize,
    /// Regions where it hits the iteration cap.
    pub iteration_limit_regions: usize,
    /// Warm start: start sets (critical regions) certified.
    pub start_sets: usize,
    /// Warm start: every stored order of each start set certified (else
    /// sorted by constraint index).
    pub any_order: bool,
    /// LPs solved.
    pub lps: usize,
    /// Merged (over-approximating) certificates: the canonical solver
    /// states whose domain was split (0 for an exact certificate; there
    /// `regions` counts the bounds memoised, `histogram` is empty and the
    /// worst region's `path` is the chain of the bound, without a point).
    pub canonical_states: usize,
    /// Union-merge mode ([`crate::certify::CertifySettings::union_merge`]):
    /// what the merging did (`None` otherwise).
    pub union: Option<super::union::UnionStats>,
    /// Time taken.
    pub elapsed: Duration,
    /// Cold: the optimal active sets found (sorted); warm: the start sets.
    pub(super) finals: Vec<Vec<(usize, u8)>>,
    /// The kept leaf regions (empty unless kept, and for a merged one).
    pub(super) leaves: Vec<Leaf>,
    /// Warm: the start region of each start set.
    pub(super) start_regions: Vec<Region>,
    /// The box's centre and half-widths (the regions are normalised).
    pub(super) centre: Vec<f64>,
    /// See [`Self::centre`].
    pub(super) half: Vec<f64>,
}

/// A normalised polyhedron `a x <= b` (rows of `a` concatenated).
pub(super) type Region = (Vec<f64>, Vec<f64>);

pub(super) fn active(set: &[(usize, u8)]) -> Vec<ActiveConstraint> {
    set.iter()
        .map(|&(index, code)| ActiveConstraint {
            index,
            side: if code & UPPER != 0 {
                Side::Upper
            } else {
                Side::Lower
            },
        })
        .collect()
}

pub(super) fn certificate(
    model: &Model,
    par: &ParametricQp,
    tally: Tally,
    (starts, start_regions): (Vec<Vec<(usize, u8)>>, Vec<Region>),
    warm_step: Option<f64>,
    lps: usize,
    elapsed: Duration,
) -> Certificate {
    let report = |w: &Option<Worst>| {
        w.as_ref().map(|w| {
            let x = &w.node.poly.centre;
            let start_set = if warm_step.is_some() {
                active(&starts[w.node.start])
            } else {
                Vec::new()
            };
            RegionReport {
                iterations: w.node.iterations,
                flops: w.node.flops,
                status: w.status,
                theta: model.theta(x, 0),
                theta_prev: warm_step.map(|_| model.theta(x, model.p)),
                radius: w.node.poly.radius,
                halfspaces: units(model, &w.node.poly.a, &w.node.poly.b),
                path: w.node.path.clone(),
                start_set,
            }
        })
    };
    let finals = if warm_step.is_some() {
        starts.clone()
    } else {
        tally.finals.iter().cloned().collect()
    };
    Certificate {
        warm_step,
        exact: true,
        n: par.n(),
        m: par.m(),
        p: par.p(),
        worst_iterations: tally
            .worst_iterations
            .as_ref()
            .map_or(0, |w| w.node.iterations),
        worst_flops: tally.worst_flops.as_ref().map_or(0, |w| w.node.flops),
        worst: report(&tally.worst_iterations),
        worst_flops_region: report(&tally.worst_flops),
        regions: tally.regions,
        histogram: tally.histogram,
        infeasible_regions: tally.infeasible,
        iteration_limit_regions: tally.limited,
        start_sets: starts.len(),
        any_order: false,
        lps,
        canonical_states: 0,
        union: None,
        elapsed,
        finals,
        leaves: tally.leaves,
        start_regions,
        centre: model.centre.clone(),
        half: model.half.clone(),
    }
}

/// Normalised rows `a s <= b` in parameter units (`s_k = (theta_k -
/// c_k) / h_k`, repeated for `theta_prev`).
fn units(model: &Model, a: &[f64], b: &[f64]) -> Vec<(Vec<f64>, f64)> {
    let d = model.d;
    a.chunks_exact(d)
        .zip(b)
        .map(|(row, &bi)| {
            let mut out = vec![0.0; d];
            let mut rhs = bi;
            for (t, &r) in row.iter().enumerate() {
                let k = t % model.p;
                if model.half[k] > 0.0 {
                    out[t] = r / model.half[k];
                    rhs += r * model.centre[k] / model.half[k];
                }
            }
            (out, rhs)
        })
        .collect()
}

impl Certificate {
    /// Whether the regions were kept ([`crate::certify::CertifySettings::keep_regions`]).
    pub fn has_regions(&self) -> bool {
        !self.leaves.is_empty()
    }

    /// The iterations and flops the certificate gives for `theta` (and,
    /// for a warm certificate, `theta_prev`): those of the region that
    /// contains the point most deeply (for a warm start in any order, the
    /// most over the orders); `None` if no kept region contains it (to
    /// `1e-9` in the normalised box), as on a dropped sliver.
    pub fn iterations_at(&self, theta: &[f64], theta_prev: Option<&[f64]>) -> Option<(usize, u64)> {
        let norm = |t: &[f64]| -> Vec<f64> {
            t.iter()
                .enumerate()
                .map(|(k, &v)| {
                    if self.half[k] > 0.0 {
                        (v - self.centre[k]) / self.half[k]
                    } else {
                        0.0
                    }
                })
                .collect()
        };
        let mut x = norm(theta);
        if self.warm_step.is_some() {
            x.extend(norm(theta_prev?));
        }
        let d = x.len();
        let slack = |a: &[f64], b: &[f64]| {
            b.iter()
                .zip(a.chunks_exact(d))
                .map(|(bi, r)| bi - r.iter().zip(&x).map(|(u, v)| u * v).sum::<f64>())
                .fold(f64::INFINITY, f64::min)
        };
        // Warm: only the start sets whose start region holds the point.
        let starts: Vec<bool> = self
            .start_regions
            .iter()
            .map(|(a, b)| slack(a, b) >= -1e-9)
            .collect();
        let mut best: Option<(f64, &Leaf)> = None;
        for leaf in &self.leaves {
            if starts.get(leaf.start) == Some(&false) {
                continue;
            }
            let s = slack(&leaf.a, &leaf.b);
            let key = |l: &Leaf, s: f64| {
                if self.any_order {
                    (l.iterations as f64, s)
                } else {
                    (s, 0.0)
                }
            };
            if s >= -1e-9 && best.is_none_or(|(t, b)| key(leaf, s) > key(b, t)) {
                best = Some((s, leaf));
            }
        }
        best.map(|(_, l)| (l.iterations, l.flops))
    }

    /// The certificate as JSON (format `kestrel.qp-certificate.v1`).
    pub fn to_json(&self) -> Value {
        let region = |r: &Option<RegionReport>| match r {
            None => Value::Null,
            Some(r) => json!({
                "iterations": r.iterations,
                "flops": r.flops,
                "status": format!("{:?}", r.status),
                "theta": r.theta,
                "theta_prev": r.theta_prev,
                "radius": r.radius,
                "path": path_text(&r.path, self.m),
                "start_set": r.start_set.iter().map(|a| format!("{}{}",
                    super::model::constraint_name(a.index, self.m),
                    if a.side == Side::Upper { "u" } else { "l" })).collect::<Vec<_>>(),
                "A": r.halfspaces.iter().map(|h| h.0.clone()).collect::<Vec<_>>(),
                "b": r.halfspaces.iter().map(|h| h.1).collect::<Vec<_>>(),
            }),
        };
        let mut doc = json!({
            "format": "kestrel.qp-certificate.v1",
            "start": if self.warm_step.is_some() { "warm" } else { "cold" },
            "warm_step": self.warm_step,
            "exact": self.exact,
            "n": self.n,
            "m": self.m,
            "p": self.p,
            "worst_iterations": self.worst_iterations,
            "worst_flops": self.worst_flops,
            "regions": self.regions,
            "histogram": self.histogram,
            "infeasible_regions": self.infeasible_regions,
            "iteration_limit_regions": self.iteration_limit_regions,
            "start_sets": self.start_sets,
            "any_order": self.any_order,
            "lps": self.lps,
            "seconds": self.elapsed.as_secs_f64(),
            "worst_region": region(&self.worst),
            "worst_flops_region": region(&self.worst_flops_region),
        });
        if !self.exact {
            doc["canonical_states"] = json!(self.canonical_states);
        }
        if let Some(u) = &self.union {
            doc["union_merge"] = json!({
                "pairs_tested": u.pairs_tested,
                "merges": u.merges,
                "flops_exact": u.flops_exact(),
                "levels": u.levels.iter().map(|l| json!({
                    "iterations": l.iterations,
                    "canonical": l.canonical,
                    "groups": l.groups,
                    "merged": l.merged,
                })).collect::<Vec<_>>(),
            });
        }
        doc
    }
}

fn fmt_vec(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.6e}")).collect();
    format!("[{}]", items.join(", "))
}

impl fmt::Display for Certificate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.warm_step {
            None => writeln!(f, "cold start (empty active set)")?,
            Some(s) => writeln!(
                f,
                "warm start (previous optimal active set, {}; |theta - theta_prev| <= {s} x box width per parameter; {} start sets)",
                if self.any_order {
                    "any stored order"
                } else {
                    "sorted by index"
                },
                self.start_sets
            )?,
        }
        let flops_bound = self.union.as_ref().is_some_and(|u| !u.flops_exact());
        writeln!(
            f,
            "  worst case: {} iterations, {} flops ({})",
            self.worst_iterations,
            self.worst_flops,
            match (self.exact, flops_bound) {
                (false, _) => "upper bound",
                (true, false) => "exact",
                (true, true) => "iterations exact, flops an upper bound",
            }
        )?;
        let hist: Vec<String> = self
            .histogram
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(i, c)| format!("{i}: {c}"))
            .collect();
        if !self.exact {
            writeln!(
                f,
                "  merged: {} canonical states split, {} bounds memoised, infeasible pieces {}, at the iteration cap {}; {} LPs, {:.2} s",
                self.canonical_states,
                self.regions,
                self.infeasible_regions,
                self.iteration_limit_regions,
                self.lps,
                self.elapsed.as_secs_f64()
            )?;
            if let Some(w) = &self.worst {
                writeln!(f, "  worst chain: {}", path_text(&w.path, self.m))?;
            }
            return Ok(());
        }
        writeln!(
            f,
            "  regions: {} (iterations: {}), infeasible {}, at the iteration cap {}; {} LPs, {:.2} s",
            self.regions,
            hist.join(", "),
            self.infeasible_regions,
            self.iteration_limit_regions,
            self.lps,
            self.elapsed.as_secs_f64()
        )?;
        if let Some(u) = &self.union {
            let canonical: usize = u.levels.iter().map(|l| l.canonical).sum();
            let merged: usize = u.levels.iter().map(|l| l.merged).sum();
            writeln!(
                f,
                "  union merge: {canonical} regions at canonical states -> {merged} ({} merges of {} pairs tested)",
                u.merges, u.pairs_tested
            )?;
        }
        if let Some(w) = &self.worst {
            writeln!(f, "  worst region: theta = {}", fmt_vec(&w.theta))?;
            if let Some(tp) = &w.theta_prev {
                writeln!(f, "                theta_prev = {}", fmt_vec(tp))?;
            }
            writeln!(
                f,
                "                path: {} (ball radius {:.3e} of the normalised box, {} half-spaces)",
                path_text(&w.path, self.m),
                w.radius,
                w.halfspaces.len()
            )?;
        }
        if let Some(w) = &self.worst_flops_region {
            writeln!(
                f,
                "  most flops: {} ({} iterations) at theta = {}",
                w.flops,
                w.iterations,
                fmt_vec(&w.theta)
            )?;
        }
        Ok(())
    }
}
