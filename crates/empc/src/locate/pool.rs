//! The facet hyperplanes of the regions, each stored once: as the
//! difference of two law rows where two regions with different laws meet
//! (the first move is continuous, so the laws agree on the facet), as a
//! row of its own otherwise. Facets on the parameter box or the explored
//! set's hull are left out: the evaluation projects onto the box and flags
//! points outside the hull before it locates.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::eval::WIDE_NO_ROW;
use crate::mpqp::MpqpSolution;
use std::collections::HashMap;

/// The hyperplanes and every region's facets.
pub(super) struct Pool {
    /// Unit normal `a` and offset `b` of each hyperplane, canonically
    /// oriented: the "below" side is `a theta <= b`.
    pub(super) planes: Vec<(Vec<f64>, f64)>,
    /// How the tables evaluate each: rows `[r1, r2]` with `r1 - r2` a
    /// positive multiple of `a theta - b` (`r2 = WIDE_NO_ROW`: zero).
    pub(super) rows: Vec<[u32; 2]>,
    /// Per region: `(hyperplane, below)`, `below` when the region lies on
    /// the side `a theta <= b`.
    pub(super) facets: Vec<Vec<(u32, bool)>>,
    /// Hyperplanes that needed a row of their own.
    pub(super) explicit: usize,
}

/// Whether the unit row `(a, b)` is a face of the box `[lb, ub]`.
fn on_box(a: &[f64], b: f64, lb: &[f64], ub: &[f64], tol: f64) -> bool {
    let Some(j) = (0..a.len()).find(|&j| a[j].abs() > 0.5) else {
        return false;
    };
    let axis = (0..a.len()).all(|i| i == j || a[i].abs() <= 1e-12);
    axis && ((a[j] - 1.0).abs() <= 1e-12 && (b - ub[j]).abs() <= tol
        || (a[j] + 1.0).abs() <= 1e-12 && (b + lb[j]).abs() <= tol)
}

/// Collects the hyperplanes of `solution`'s facets and represents them by
/// the rows of `rows` (width `p + 1`, extended by the explicit ones);
/// `law_rows[region]` are the region's law rows (one per kept output).
/// `progress(done)` is called every 256 regions.
pub(super) fn collect(
    solution: &MpqpSolution,
    law_rows: &[&[u32]],
    rows: &mut Vec<f64>,
    progress: &mut dyn FnMut(usize),
) -> Pool {
    let p = solution.p;
    let w = p + 1;
    let lb = solution.theta_lb.as_slice();
    let ub = solution.theta_ub.as_slice();
    let scale = 1.0 + lb.iter().chain(ub).fold(0.0_f64, |s, v| s.max(v.abs()));
    let hull: Vec<(Vec<f64>, f64)> = (0..solution.hull_a.nrows())
        .filter_map(|i| {
            let a: Vec<f64> = solution.hull_a.row(i).iter().copied().collect();
            let n = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            (n > 0.0).then(|| (a.iter().map(|v| v / n).collect(), solution.hull_b[i] / n))
        })
        .collect();
    let mut planes: Vec<(Vec<f64>, f64)> = Vec::new();
    let mut members: Vec<Vec<(u32, bool)>> = Vec::new();
    let mut index: HashMap<Vec<i64>, u32> = HashMap::new();
    let mut facets = Vec::with_capacity(solution.regions.len());
    for (ri, r) in solution.regions.iter().enumerate() {
        if ri % 256 == 0 {
            progress(ri);
        }
        let mut fs = Vec::with_capacity(r.a.nrows());
        for i in 0..r.a.nrows() {
            let a: Vec<f64> = r.a.row(i).iter().copied().collect();
            let b = r.b[i];
            let tol = 1e-9 * scale;
            if on_box(&a, b, lb, ub, tol)
                || hull.iter().any(|(ha, hb)| {
                    (hb - b).abs() <= tol && ha.iter().zip(&a).all(|(x, y)| (x - y).abs() <= 1e-9)
                })
            {
                continue;
            }
            let lead = a.iter().copied().find(|v| v.abs() > 1e-9).unwrap_or(1.0);
            let sgn = if lead < 0.0 { -1.0 } else { 1.0 };
            let ca: Vec<f64> = a.iter().map(|v| v * sgn).collect();
            let cb = b * sgn;
            let key: Vec<i64> = ca
                .iter()
                .map(|v| (v * 1e8).round() as i64)
                .chain([(cb / scale * 1e8).round() as i64])
                .collect();
            let id = *index.entry(key).or_insert_with(|| {
                planes.push((ca, cb));
                members.push(Vec::new());
                (planes.len() - 1) as u32
            });
            let below = sgn > 0.0;
            if !fs.iter().any(|&(h, _)| h == id) {
                fs.push((id, below));
                members[id as usize].push((ri as u32, below));
            }
        }
        facets.push(fs);
    }
    let rmax = 1.0 + rows.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
    let mut prow = Vec::with_capacity(planes.len());
    let mut explicit = 0;
    for (h, (a, b)) in planes.iter().enumerate() {
        match as_difference(a, *b, &members[h], law_rows, rows, w, scale, rmax) {
            Some(pair) => prow.push(pair),
            None => {
                let r = (rows.len() / w) as u32;
                rows.extend_from_slice(a);
                rows.push(-b);
                prow.push([r, WIDE_NO_ROW]);
                explicit += 1;
            }
        }
    }
    Pool {
        planes,
        rows: prow,
        facets,
        explicit,
    }
}

/// Two law rows whose difference is a positive multiple `c` of
/// `a theta - b` (to `1e-9` of the rows' size, `c` not below that), the
/// largest `c` of the first 64 pairs of regions on the two sides.
#[allow(clippy::too_many_arguments)]
fn as_difference(
    a: &[f64],
    b: f64,
    members: &[(u32, bool)],
    law_rows: &[&[u32]],
    rows: &[f64],
    w: usize,
    scale: f64,
    rmax: f64,
) -> Option<[u32; 2]> {
    let p = w - 1;
    let tol = 1e-9 * rmax * scale;
    let mut best: Option<([u32; 2], f64)> = None;
    let mut tried = 0;
    for &(r1, _) in members.iter().filter(|m| m.1) {
        for &(r2, _) in members.iter().filter(|m| !m.1) {
            tried += 1;
            if tried > 64 {
                return best.map(|x| x.0);
            }
            for (&x, &y) in law_rows[r1 as usize].iter().zip(law_rows[r2 as usize]) {
                if x == y {
                    continue;
                }
                let (u, v) = (&rows[x as usize * w..][..w], &rows[y as usize * w..][..w]);
                let c: f64 = (0..p).map(|j| (u[j] - v[j]) * a[j]).sum();
                if c.abs() <= tol {
                    continue;
                }
                let err = (0..p)
                    .map(|j| (u[j] - v[j] - c * a[j]).abs() * scale)
                    .fold((u[p] - v[p] + c * b).abs(), f64::max);
                if err <= tol && best.is_none_or(|bst| c.abs() > bst.1) {
                    // Below (a theta <= b) is the region r1's side.
                    let pair = if c > 0.0 { [x, y] } else { [y, x] };
                    best = Some((pair, c.abs()));
                }
            }
        }
    }
    best.map(|x| x.0)
}
