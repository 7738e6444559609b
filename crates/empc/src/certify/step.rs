//! One iteration of kestrel-qp's dual active-set method over a region of
//! parameters: the region is split by every decision the solver makes
//! (blocking constraint of the dual step, the constraint a singular step
//! removes, the most violated constraint, optimality), each piece
//! becoming a region with one more active-set change.
//!
//! The decision rules mirror `crates/qp/src/iterate.rs` (frozen in the
//! issue-24 plan). Every comparison is affine in the parameter: after a
//! constraint `k` is added, `M mu` equals the right-hand side on every row
//! but `k`'s (the previous multipliers solve the previous set), so `mu* -
//! mu = r(theta) M^-1 e_k` with a constant direction and the sign of `r`
//! that of `k`'s side; the blocking ratios `alpha_i = cur_i / (cur_i -
//! star_i)` then compare through `sign(r) (cur_i w_j - cur_j w_i) < 0`
//! with constant `w` (Arnström and Axehill's certification of the dual
//! method, ASCertain.jl). A removal keeps that invariant (the removed
//! multiplier is exactly zero), so do singular steps (they move `mu`
//! along the null vector of `M`). Before the first addition of a warm
//! start `mu = 0`, every ratio is 0, and the first blocking position wins.

use super::error::CertifyError;
use super::flops;
use super::geometry::{Geometry, Half, Poly, half, half_tie, identical, minus, size};
use super::model::{EQUALITY, Model, UPPER, axpy, sign};

/// One active-set change of a path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Change {
    /// The most violated constraint entered (index as in kestrel-qp:
    /// solver rows, then the bound on `z_i` at `m + i`), on its upper side
    /// or not.
    Add {
        /// The constraint.
        constraint: usize,
        /// Its upper bound (else the lower).
        upper: bool,
    },
    /// A blocking constraint left in a dual step.
    Remove {
        /// The constraint.
        constraint: usize,
    },
    /// A constraint left in a singular step (the entering one depended on
    /// the active ones).
    Singular {
        /// The constraint.
        constraint: usize,
    },
}

/// How a region's solve ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// At the optimum.
    Optimal,
    /// `QpError::Infeasible`.
    Infeasible,
    /// `QpError::IterationLimit` (the settings' cap).
    IterationLimit,
}

/// A region of parameters with the solver's state after its path so far.
#[derive(Debug, Clone)]
pub(super) struct Node {
    pub poly: Poly,
    pub active: Vec<(usize, u8)>,
    /// Multipliers, one affine function per position.
    pub mu: Vec<Vec<f64>>,
    /// False while `mu = 0` after a warm start (before the first addition).
    pub dual: bool,
    /// The last active constraint got a zero pivot.
    pub singular: bool,
    /// Positions whose forward solve the solver keeps (its `fwd_valid`).
    pub fwd: usize,
    pub iterations: usize,
    pub flops: u64,
    pub path: Vec<Change>,
    /// Index of the warm-start set (0 for a cold start).
    pub start: usize,
    /// Union-merge mode (`crate::certify::union`): the region merges
    /// pieces whose active lists had different orders (this one or an
    /// ancestor), so the list is one member's order: a removal is charged
    /// its most flops, and an order-decided tie is counted in
    /// [`Geometry::order_ties`].
    pub mixed: bool,
}

/// A piece of a split region.
#[derive(Debug)]
pub(super) enum Outcome {
    /// Continues with another iteration.
    Node(Node),
    /// The solve ends here.
    Leaf(Node, Status),
    /// Merged mode ([`Model::merge`]): a full dual step reached the
    /// canonical state of the active set (`mu = mu*`); the solver's future
    /// depends on the set and the parameter only (`crate::certify::merge`).
    Canonical(Node),
}

fn numerical(what: &str) -> CertifyError {
    CertifyError::Numerical(what.to_string())
}

/// `mu_q <- mu_q + c_q t` for an affine `t` and constants `c`, then the
/// position `p` removed.
fn moved(mu: &[Vec<f64>], t: &[f64], c: &[f64], p: usize) -> Vec<Vec<f64>> {
    mu.iter()
        .zip(c)
        .enumerate()
        .filter(|&(q, _)| q != p)
        .map(|(_, (m, &cq))| {
            let mut f = m.clone();
            axpy(&mut f, cq, t);
            f
        })
        .collect()
}

fn removed(mut node: Node, poly: Poly, p: usize, mu: Vec<Vec<f64>>, change: Change) -> Node {
    node.poly = poly;
    node.active.remove(p);
    node.mu = mu;
    node.singular = false;
    node.iterations += 1;
    node.path.push(change);
    node
}

/// Splits `node` by its next iteration into `out`.
pub(super) fn expand(
    model: &Model,
    geo: &mut Geometry,
    node: Node,
    out: &mut Vec<Outcome>,
) -> Result<(), CertifyError> {
    let k = node.active.len();
    let limit = model.settings.max_iterations;
    if k > 0 && node.singular {
        if node.iterations >= limit {
            out.push(Outcome::Leaf(node, Status::IterationLimit));
            return Ok(());
        }
        return singular_step(model, geo, node, out);
    }
    let mustar = model
        .mustar(&node.active)
        .ok_or_else(|| numerical("M of an active set is singular"))?;
    let free_count = node.active.iter().filter(|a| a.1 & EQUALITY == 0).count() as u64;
    // mu* and the blocking test when nothing blocks; a blocking piece adds
    // 3 per position that may block there (an upper bound).
    let top = flops::mustar(k as u64, node.fwd as u64) + flops::blocking(free_count, 0);
    let dtol = model.settings.dual_tol;
    let star: Vec<Vec<f64>> = (0..k)
        .map(|p| {
            let s = sign(node.active[p].1);
            mustar[p].iter().map(|v| s * v).collect()
        })
        .collect();
    // star_p < -dtol, and its negation.
    let blocks = |p: usize| {
        let mut f = star[p].clone();
        f[model.d] += dtol;
        half(&f, true, size(&star[p]))
    };
    let holds = |p: usize| {
        let mut f: Vec<f64> = star[p].iter().map(|v| -v).collect();
        f[model.d] -= dtol;
        half(&f, false, size(&star[p]))
    };
    let free = |p: usize| node.active[p].1 & EQUALITY == 0;
    let mut feasible: Vec<Half> = Vec::new();
    if k > 0 && !node.dual {
        // mu = 0: every ratio is 0, the first blocking position wins.
        let cands: Vec<usize> = (0..k).filter(|&p| free(p)).collect();
        for (t, &p) in cands.iter().enumerate() {
            let mut hs = vec![blocks(p)];
            hs.extend(cands[..t].iter().map(|&q| holds(q)));
            if let Some(poly) = geo.restrict(&node.poly, &hs) {
                if node.iterations >= limit {
                    let mut leaf = node.clone();
                    leaf.poly = poly;
                    out.push(Outcome::Leaf(leaf, Status::IterationLimit));
                    continue;
                }
                let mut child = node.clone();
                // The earlier positions do not block, `p` and later may.
                let at = model.position(p, node.mixed);
                child.flops += top
                    + flops::blocking(0, (cands.len() - t) as u64)
                    + flops::dual_step(k as u64)
                    + flops::remove(k as u64, at as u64);
                child.fwd = at;
                let mu = node.mu.iter().enumerate().filter(|&(q, _)| q != p);
                let mu = mu.map(|(_, m)| m.clone()).collect();
                let c = Change::Remove {
                    constraint: node.active[p].0,
                };
                out.push(Outcome::Node(removed(child, poly, p, mu, c)));
            }
        }
        feasible.extend(cands.iter().map(|&p| holds(p)));
    } else if k > 0 {
        let v = model
            .last_column(&node.active)
            .ok_or_else(|| numerical("M of an active set is singular"))?;
        let last = k - 1;
        let sk = sign(node.active[last].1);
        // mu* - mu = r v: check the invariant the affine comparisons need.
        let delta: Vec<Vec<f64>> = (0..k).map(|p| minus(&mustar[p], &node.mu[p])).collect();
        let vmax = v.iter().fold(0.0_f64, |s, x| s.max(x.abs()));
        let r: Vec<f64> = delta[last].iter().map(|x| x / v[last]).collect();
        let dscale = delta.iter().map(|f| size(f)).fold(0.0, f64::max) + size(&r) * vmax;
        for (dp, &vp) in delta.iter().zip(&v) {
            let err = dp
                .iter()
                .zip(&r)
                .fold(0.0_f64, |s, (a, b)| s.max((a - b * vp).abs()));
            if err > 1e-7 * dscale.max(f64::MIN_POSITIVE) {
                return Err(numerical(
                    "mu* - mu is not a multiple of M^-1 e_k (the dual-step invariant failed)",
                ));
            }
        }
        let w: Vec<f64> = (0..k).map(|p| -sign(node.active[p].1) * v[p]).collect();
        let cands: Vec<usize> = (0..k)
            .filter(|&p| free(p) && sk * w[p] > 1e-12 * vmax)
            .collect();
        let cur: Vec<Vec<f64>> = (0..k)
            .map(|p| {
                let s = sign(node.active[p].1);
                node.mu[p].iter().map(|x| s * x).collect()
            })
            .collect();
        for &i in &cands {
            let mut hs = vec![blocks(i)];
            for &j in &cands {
                if j == i {
                    continue;
                }
                // alpha_i < alpha_j  <=>  sk (cur_i w_j - cur_j w_i) < 0.
                let f: Vec<f64> = cur[i]
                    .iter()
                    .zip(&cur[j])
                    .map(|(a, b)| sk * (a * w[j] - b * w[i]))
                    .collect();
                let sc = size(&cur[i]) * w[j].abs() + size(&cur[j]) * w[i].abs();
                if node.mixed && identical(&f, sc) {
                    geo.order_ties += 1;
                }
                hs.push(half_tie(&f, j < i, sc, model.merge));
            }
            if let Some(poly) = geo.restrict(&node.poly, &hs) {
                if node.iterations >= limit {
                    let mut leaf = node.clone();
                    leaf.poly = poly;
                    out.push(Outcome::Leaf(leaf, Status::IterationLimit));
                    continue;
                }
                // mu + alpha_i (mu* - mu) = mu - (mu_i / v_i) v.
                let t: Vec<f64> = node.mu[i].iter().map(|x| -x / v[i]).collect();
                let mu = moved(&node.mu, &t, &v, i);
                let mut child = node.clone();
                let at = model.position(i, node.mixed);
                child.flops += top
                    + flops::blocking(0, cands.len() as u64)
                    + flops::dual_step(k as u64)
                    + flops::remove(k as u64, at as u64);
                child.fwd = at;
                let c = Change::Remove {
                    constraint: node.active[i].0,
                };
                out.push(Outcome::Node(removed(child, poly, i, mu, c)));
            }
        }
        feasible.extend(cands.iter().map(|&p| holds(p)));
    }
    let Some(poly) = geo.restrict(&node.poly, &feasible) else {
        return Ok(());
    };
    let mut node = node;
    node.poly = poly;
    node.mu = mustar;
    node.dual = true;
    node.flops += top;
    node.fwd = k;
    if model.canonical {
        out.push(Outcome::Canonical(node));
    } else {
        add_step(model, geo, node, out);
    }
    Ok(())
}

/// The dual-feasible branch: the primal point and the most violated
/// constraint (or the optimum).
pub(super) fn add_step(model: &Model, geo: &mut Geometry, node: Node, out: &mut Vec<Outcome>) {
    let (n, k) = (model.n, node.active.len());
    let d = model.d;
    let ptol = model.settings.primal_tol;
    let mut inactive = vec![true; model.ncons];
    for &(j, _) in &node.active {
        inactive[j] = false;
    }
    let count = |range: std::ops::Range<usize>| range.filter(|&j| inactive[j]).count() as u64;
    let scan = flops::primal(n as u64, k as u64)
        + flops::scan(n as u64, count(0..model.rows), count(0..model.ncons));
    // (constraint, upper, violation) of every finite side.
    let mut cands: Vec<(usize, bool, Vec<f64>)> = Vec::new();
    for j in (0..model.ncons).filter(|&j| inactive[j]) {
        let v = model.value(j, &node.active, &node.mu);
        if let Some(hi) = &model.hi[j] {
            cands.push((j, true, minus(&v, hi)));
        }
        if let Some(lo) = &model.lo[j] {
            cands.push((j, false, minus(lo, &v)));
        }
    }
    // viol > ptol  <=>  ptol - viol < 0.
    let exceeds = |f: &Vec<f64>| {
        let mut g: Vec<f64> = f.iter().map(|x| -x).collect();
        g[d] += ptol;
        half(&g, true, size(f))
    };
    let within = |f: &Vec<f64>| {
        let mut g = f.clone();
        g[d] -= ptol;
        half(&g, false, size(f))
    };
    let optimal: Vec<Half> = cands.iter().map(|c| within(&c.2)).collect();
    if let Some(poly) = geo.restrict(&node.poly, &optimal) {
        let mut leaf = node.clone();
        leaf.poly = poly;
        leaf.flops += scan;
        out.push(Outcome::Leaf(leaf, Status::Optimal));
    }
    for (t, (j, upper, viol)) in cands.iter().enumerate() {
        let mut hs = vec![exceeds(viol)];
        for (u, (j2, _, viol2)) in cands.iter().enumerate() {
            if u == t {
                continue;
            }
            // The solver keeps the first of equal violations: a later
            // constraint must exceed strictly; the upper side of the same
            // constraint wins only if strictly larger.
            let strict = if j2 == j { *upper } else { j2 < j };
            hs.push(half(&minus(viol2, viol), strict, size(viol) + size(viol2)));
        }
        let Some(poly) = geo.restrict(&node.poly, &hs) else {
            continue;
        };
        let mut child = node.clone();
        child.poly = poly;
        if node.iterations >= model.settings.max_iterations {
            out.push(Outcome::Leaf(child, Status::IterationLimit));
            continue;
        }
        if k > n {
            out.push(Outcome::Leaf(child, Status::Infeasible));
            continue;
        }
        let code = u8::from(*upper) * UPPER + if model.equality[*j] { EQUALITY } else { 0 };
        child.singular = model.dependent(&node.active, *j);
        child.active.push((*j, code));
        child.mu.push(vec![0.0; d + 1]);
        child.iterations += 1;
        let rows_active = node.active.iter().filter(|a| a.0 < model.rows).count() as u64;
        child.flops += scan + flops::add(n as u64, k as u64, *j < model.rows, rows_active);
        child.path.push(Change::Add {
            constraint: *j,
            upper: *upper,
        });
        out.push(Outcome::Node(child));
    }
}

/// The last active constraint depends on the others: move `mu` along the
/// null vector of `M` until the first multiplier reaches zero.
fn singular_step(
    model: &Model,
    geo: &mut Geometry,
    node: Node,
    out: &mut Vec<Outcome>,
) -> Result<(), CertifyError> {
    let k = node.active.len();
    let last = k - 1;
    let pv = model
        .null_vector(&node.active)
        .ok_or_else(|| numerical("the active set before a dependent constraint is singular"))?;
    let sk = sign(node.active[last].1);
    let pmax = pv.iter().fold(0.0_f64, |s, x| s.max(x.abs()));
    let free = (0..last)
        .filter(|&i| node.active[i].1 & EQUALITY == 0)
        .count();
    let cands: Vec<(usize, f64)> = (0..last)
        .filter(|&i| node.active[i].1 & EQUALITY == 0)
        .map(|i| (i, sign(node.active[i].1) * sk * pv[i]))
        .filter(|&(_, rate)| rate < -model.settings.dual_tol * pmax)
        .collect();
    if cands.is_empty() {
        out.push(Outcome::Leaf(node, Status::Infeasible));
        return Ok(());
    }
    // tau_i = s_i mu_i / (-rate_i).
    let tau: Vec<Vec<f64>> = cands
        .iter()
        .map(|&(i, rate)| {
            let s = sign(node.active[i].1);
            node.mu[i].iter().map(|x| s * x / (-rate)).collect()
        })
        .collect();
    let step: Vec<f64> = pv.iter().map(|x| sk * x).collect();
    for (t, &(i, _)) in cands.iter().enumerate() {
        let hs: Vec<Half> = cands
            .iter()
            .enumerate()
            .filter(|&(u, _)| u != t)
            .map(|(u, &(j, _))| {
                let f = minus(&tau[t], &tau[u]);
                let sc = size(&tau[t]) + size(&tau[u]);
                if node.mixed && identical(&f, sc) {
                    geo.order_ties += 1;
                }
                half_tie(&f, j < i, sc, model.merge)
            })
            .collect();
        if let Some(poly) = geo.restrict(&node.poly, &hs) {
            let mu = moved(&node.mu, &tau[t], &step, i);
            let mut child = node.clone();
            let at = model.position(i, node.mixed);
            child.flops += flops::singular(k as u64, free as u64, cands.len() as u64)
                + flops::remove(k as u64, at as u64);
            child.fwd = child.fwd.min(at);
            let c = Change::Singular {
                constraint: node.active[i].0,
            };
            out.push(Outcome::Node(removed(child, poly, i, mu, c)));
        }
    }
    Ok(())
}
