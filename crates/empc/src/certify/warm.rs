//! The warm start's roots: the start region of a stored active set in
//! `(theta, theta_prev)` and the solver's state after re-adding it.

use super::error::CertifyError;
use super::flops;
use super::geometry::{Geometry, Half, Poly, half, minus, size};
use super::model::{EQUALITY, Model, sign};
use super::step::Node;

/// Every order of `set` (at most 8! = 40,320).
pub(super) fn permutations(set: &[(usize, u8)]) -> Result<Vec<Vec<(usize, u8)>>, CertifyError> {
    if set.len() > 8 {
        return Err(CertifyError::InvalidSettings(format!(
            "warm_any_order: a start set has {} constraints, more than 8! orders",
            set.len()
        )));
    }
    let mut out = vec![Vec::new()];
    for &c in set {
        out = out
            .into_iter()
            .flat_map(|o: Vec<(usize, u8)>| {
                (0..=o.len()).map(move |i| {
                    let mut v = o.clone();
                    v.insert(i, c);
                    v
                })
            })
            .collect();
    }
    Ok(out)
}

/// The start region of a warm start from `set`: `theta_prev` (columns
/// `p..2p`) in the critical region of `set`, `theta` in the box and
/// within the step.
pub(super) fn warm_region(
    cold: &Model,
    geo: &mut Geometry,
    set: &[(usize, u8)],
    step: f64,
) -> Option<Poly> {
    let p = cold.p;
    let d = 2 * p;
    let lift = |f: &[f64]| {
        let mut g = vec![0.0; d + 1];
        g[p..d].copy_from_slice(&f[..p]);
        g[d] = f[p];
        g
    };
    let mut hs: Vec<Half> = Vec::new();
    // |s_k - sp_k| <= 2 step (the box is [-1, 1]).
    for k in 0..p {
        for sgn in [1.0, -1.0] {
            let mut row = vec![0.0; d];
            row[k] = sgn / 2f64.sqrt();
            row[p + k] = -sgn / 2f64.sqrt();
            hs.push(Half::Row(row, 2.0 * step / 2f64.sqrt()));
        }
    }
    let mustar = cold.mustar(set)?;
    for (&(_, code), m) in set.iter().zip(&mustar) {
        if code & EQUALITY == 0 {
            let f: Vec<f64> = m.iter().map(|v| -sign(code) * v).collect();
            hs.push(half(&lift(&f), false, size(m)));
        }
    }
    let mut active = vec![false; cold.ncons];
    for &(j, _) in set {
        active[j] = true;
    }
    for j in (0..cold.ncons).filter(|&j| !active[j]) {
        let v = cold.value(j, set, &mustar);
        if let Some(hi) = &cold.hi[j] {
            let f = minus(&v, hi);
            hs.push(half(&lift(&f), false, size(&v) + size(hi)));
        }
        if let Some(lo) = &cold.lo[j] {
            let f = minus(lo, &v);
            hs.push(half(&lift(&f), false, size(&v) + size(lo)));
        }
    }
    // theta and theta_prev both in the parameter set.
    hs.extend(cold.param_halfs(0, d));
    hs.extend(cold.param_halfs(p, d));
    geo.restrict(&Poly::cube(d), &hs)
}

/// The solver's state after re-adding `set` (sorted) from `mu = 0`:
/// dependent constraints and infinite bounds dropped.
pub(super) fn warm_root(model: &Model, set: &[(usize, u8)], poly: Poly, id: usize, n: u64) -> Node {
    let mut active: Vec<(usize, u8)> = Vec::new();
    let mut flops = flops::preamble(n);
    for &(j, code) in set {
        if model.bound(j, code).is_none() || active.len() > model.n {
            continue;
        }
        let rows = active.iter().filter(|a| a.0 < model.rows).count() as u64;
        flops += flops::add(n, active.len() as u64, j < model.rows, rows);
        if !model.dependent(&active, j) {
            active.push((j, code));
        }
    }
    let k = active.len();
    Node {
        poly,
        active,
        mu: vec![vec![0.0; model.d + 1]; k],
        dual: false,
        singular: false,
        fwd: 0,
        iterations: 0,
        flops,
        path: Vec::new(),
        start: id,
        mixed: false,
    }
}
