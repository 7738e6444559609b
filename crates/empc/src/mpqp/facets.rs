//! The geometry of a region: its largest inscribed ball and its facets
//! (rays from an interior point, then Clarkson's LPs for the rest).
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::lp::{LpStatus, LpWorkspace, slack_start};
use crate::mpqp::prepare::Prepared;
use crate::mpqp::region::{Facet, Origin, seed_of};
use crate::rng::Rng;

impl Prepared {
    /// Largest ball in `{x : a x <= b}` (unit rows, `rows x p`), optionally on the
    /// hyperplane of row `on` (which then gets no radius term).
    pub(super) fn chebyshev(
        &self,
        a: &[f64],
        b: &[f64],
        on: Option<usize>,
        lp: &mut LpWorkspace,
        buf: &mut (Vec<f64>, Vec<f64>),
    ) -> Option<(Vec<f64>, f64)> {
        let p = self.p;
        let d = p + 1;
        let rows = b.len();
        let (la, lb) = buf;
        la.clear();
        lb.clear();
        for i in 0..rows {
            la.extend_from_slice(&a[i * p..(i + 1) * p]);
            la.push(if Some(i) == on { 0.0 } else { 1.0 });
            lb.push(b[i]);
        }
        if let Some(k) = on {
            for j in 0..p {
                la.push(-a[k * p + j]);
            }
            la.push(0.0);
            lb.push(-b[k]);
        }
        // r <= scale keeps the LP bounded.
        la.extend(std::iter::repeat_n(0.0, p));
        la.push(1.0);
        lb.push(self.scale);
        let mut c = vec![0.0; d];
        c[p] = 1.0;
        // Start: the box centre (on the hyperplane `on`), r its smallest slack.
        let mut x0: Vec<f64> = (0..p)
            .map(|j| 0.5 * (self.theta_lb[j] + self.theta_ub[j]))
            .chain([0.0])
            .collect();
        if let Some(k) = on {
            let ak = &a[k * p..(k + 1) * p];
            let s = ak.iter().zip(&x0).map(|(u, v)| u * v).sum::<f64>() - b[k];
            for j in 0..p {
                x0[j] -= s * ak[j];
            }
        }
        slack_start(la, lb, &mut x0, p);
        let (st, r) = lp.maximize_from(&c, la, lb, &x0);
        if st != LpStatus::Optimal {
            return None;
        }
        Some((lp.x[..p].to_vec(), r))
    }

    /// A box containing `{x in the parameter box : a x <= b}` (unit rows,
    /// `rows x p`): a few rounds of bound propagation, each row bounding
    /// each coordinate by the smallest value the other terms take on the
    /// current box. Every bound it gives is implied by the rows.
    pub(super) fn implied_box(&self, a: &[f64], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let p = self.p;
        let mut lo: Vec<f64> = self.theta_lb.iter().copied().collect();
        let mut hi: Vec<f64> = self.theta_ub.iter().copied().collect();
        for _ in 0..3 {
            let mut changed = false;
            for (r, &bi) in a.chunks_exact(p).zip(b) {
                let low = |j: usize, lo: &[f64], hi: &[f64]| (r[j] * lo[j]).min(r[j] * hi[j]);
                let total: f64 = (0..p).map(|j| low(j, &lo, &hi)).sum();
                if !total.is_finite() {
                    continue;
                }
                for j in 0..p {
                    // Coefficients below 1e-6 would amplify rounding.
                    if r[j].abs() < 1e-6 {
                        continue;
                    }
                    let bound = (bi - (total - low(j, &lo, &hi))) / r[j];
                    if r[j] > 0.0 && bound < hi[j] {
                        hi[j] = bound;
                        changed = true;
                    } else if r[j] < 0.0 && bound > lo[j] {
                        lo[j] = bound;
                        changed = true;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        (lo, hi)
    }

    /// Finds the facets of `{a x <= b}` (unit rows) around the interior point `c`.
    ///
    /// Rays from `c` find most facets without an LP (the first hyperplane a
    /// ray meets, if met alone, is a facet and the hit point lies inside
    /// it). Each remaining row is then decided with one small LP over the
    /// facets known so far plus the parameter rows (Clarkson's method): if
    /// the row cannot be violated it is redundant, else a ray towards the
    /// LP optimum reveals another facet.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn facets(
        &self,
        a: &[f64],
        b: &[f64],
        origins: &[Vec<Origin>],
        c: &[f64],
        act: &[usize],
        lp: &mut LpWorkspace,
        buf: &mut (Vec<f64>, Vec<f64>),
        lps: &mut usize,
    ) -> Vec<Facet> {
        let p = self.p;
        let nh = b.len();
        let row = |i: usize| &a[i * p..(i + 1) * p];
        let dot = crate::lp::dot;
        let slack: Vec<f64> = (0..nh).map(|i| b[i] - dot(row(i), c)).collect();
        let tol = self.radius_tol;
        // First hit of the ray c + t dir: (row, t), if one row is hit first.
        // `ads` keeps a_i'dir for the margin below.
        let mut ads = vec![0.0; nh];
        let first_hit = |dir: &[f64], ads: &mut [f64]| -> Option<(usize, f64)> {
            let mut best = (usize::MAX, f64::INFINITY);
            let mut second = f64::INFINITY;
            for i in 0..nh {
                let ad = dot(row(i), dir);
                ads[i] = ad;
                if ad > 1e-12 {
                    let t = slack[i] / ad;
                    if t < best.1 {
                        second = best.1;
                        best = (i, t);
                    } else if t < second {
                        second = t;
                    }
                }
            }
            let (j, t) = best;
            let gap_ok = matches!(
                (second - t).partial_cmp(&1e-9),
                Some(std::cmp::Ordering::Greater)
            );
            (j != usize::MAX && gap_ok).then_some((j, t))
        };
        // The hit point and its distance, inside the facet's hyperplane, to
        // the other hyperplanes (a_i'pt = b_i - slack_i + t a_i'dir needs no
        // second product); `None` if below the tolerance. `inv_sin` caches
        // 1 / sin(angle between rows j and i) per row j (0: parallel),
        // filled when row j is first hit (`sin_done`).
        let mut inv_sin = vec![0.0; nh * nh];
        let mut sin_done = vec![false; nh];
        let mut facet_at =
            |j: usize, t: f64, dir: &[f64], ads: &[f64]| -> Option<(usize, Vec<f64>, f64)> {
                let gj = &mut inv_sin[j * nh..(j + 1) * nh];
                if !sin_done[j] {
                    let aj = row(j);
                    for i in 0..nh {
                        let cosang = dot(row(i), aj);
                        let sin = (1.0 - cosang * cosang).max(0.0).sqrt();
                        gj[i] = if i != j && sin > 1e-9 { 1.0 / sin } else { 0.0 };
                    }
                    sin_done[j] = true;
                }
                let mut margin = f64::INFINITY;
                for i in 0..nh {
                    if gj[i] != 0.0 {
                        margin = margin.min((slack[i] - t * ads[i]) * gj[i]);
                    }
                }
                let margin = margin.min(self.scale);
                if margin > tol {
                    let pt: Vec<f64> = (0..p).map(|k| c[k] + t * dir[k]).collect();
                    Some((j, pt, margin))
                } else {
                    None
                }
            };
        let mut state = vec![0u8; nh]; // 0 unknown, 1 facet, 2 redundant
        let mut dir: Vec<f64> = Vec::with_capacity(p);
        let mut facets: Vec<Facet> = Vec::new();
        let mut rng = Rng::new(seed_of(act) ^ 0x5555);
        let add =
            |j: usize, pt: Vec<f64>, margin: f64, state: &mut [u8], facets: &mut Vec<Facet>| {
                if state[j] != 1 {
                    state[j] = 1;
                    facets.push(Facet {
                        hs: j,
                        point: pt,
                        radius: margin,
                    });
                }
            };
        for k in 0..nh {
            if state[k] != 0 {
                continue;
            }
            dir.clear();
            dir.extend((0..p).map(|q| row(k)[q] + 1e-3 * rng.sym()));
            if let Some((j, t)) = first_hit(&dir, &mut ads)
                && state[j] != 1
                && let Some((j, pt, mg)) = facet_at(j, t, &dir, &ads)
            {
                add(j, pt, mg, &mut state, &mut facets);
            }
        }
        // A box around the region by bound propagation (every row holds on
        // the region, so each row bounds one coordinate given the box of the
        // others); a row that stays clear of this box by a margin does not
        // touch the region, so it is not a facet: no LP for it. (A facet has
        // points of the region on its hyperplane, which lie in the box.)
        let (lo, hi) = self.implied_box(a, b);
        for k in 0..nh {
            if state[k] == 0 {
                let top: f64 = row(k)
                    .iter()
                    .zip(lo.iter().zip(&hi))
                    .map(|(&v, (&l, &u))| (v * l).max(v * u))
                    .sum();
                if top <= b[k] - 1e-9 * self.scale {
                    state[k] = 2;
                }
            }
        }
        let mut la: Vec<f64> = Vec::new();
        let mut lb: Vec<f64> = Vec::new();
        for k in 0..nh {
            let mut guard = 0;
            while state[k] == 0 {
                guard += 1;
                la.clear();
                lb.clear();
                for i in 0..nh {
                    if i != k && (state[i] == 1 || origins[i].contains(&Origin::Param)) {
                        la.extend_from_slice(row(i));
                        lb.push(b[i]);
                    }
                }
                la.extend_from_slice(row(k));
                lb.push(b[k] + self.scale);
                *lps += 1;
                let level = b[k] + 1e-9 * self.scale;
                let (st, val) = lp.maximize_until(row(k), &la, &lb, c, level);
                if st == LpStatus::Optimal && val <= level {
                    state[k] = 2;
                    break;
                }
                let mut found = None;
                if st == LpStatus::Optimal && guard < 50 {
                    dir.clear();
                    dir.extend((0..p).map(|q| lp.x[q] - c[q]));
                    found = first_hit(&dir, &mut ads)
                        .filter(|&(j, _)| state[j] != 1)
                        .and_then(|(j, t)| facet_at(j, t, &dir, &ads));
                }
                match found {
                    Some((j, pt, mg)) if state[j] != 1 => add(j, pt, mg, &mut state, &mut facets),
                    _ => {
                        // Ambiguous ray: decide row k exactly.
                        *lps += 1;
                        match self.chebyshev(a, b, Some(k), lp, buf) {
                            Some((pt, r)) if r > tol => add(k, pt, r, &mut state, &mut facets),
                            _ => state[k] = 2,
                        }
                    }
                }
            }
        }
        facets.sort_by_key(|f| f.hs);
        facets
    }
}
