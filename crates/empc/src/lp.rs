//! A small dense linear-programming solver (design time).
//!
//! `maximise c'x subject to A x <= b` with `x` free is solved through its
//! dual in standard form, `minimise b'y subject to A'y = c, y >= 0`, by a
//! two-phase tableau simplex. The tableau has one row per primal variable
//! (the parameters plus one, at most a dozen here) and one column per
//! constraint, so every pivot is a few hundred multiply-adds: much cheaper
//! than a general-purpose sparse solver for the thousands of tiny LPs of a
//! region exploration. The primal solution is read back from the simplex
//! multipliers. Dantzig's rule is used, with Bland's rule after a run of
//! degenerate pivots to rule out cycling.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

/// Outcome of an LP solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LpStatus {
    /// An optimum was found.
    Optimal,
    /// The constraints admit no point.
    Infeasible,
    /// The objective is unbounded above (or the dual is infeasible).
    Unbounded,
    /// The iteration limit was hit.
    NotConverged,
}

/// Caller-owned workspace of the LP solver (reused across solves).
#[derive(Default, Debug)]
pub(crate) struct LpWorkspace {
    t: Vec<f64>,
    obj: Vec<f64>,
    basis: Vec<usize>,
    sign: Vec<f64>,
    /// The primal solution of the last optimal solve.
    pub x: Vec<f64>,
}

const PIV_TOL: f64 = 1e-11;

impl LpWorkspace {
    /// maximise `c'x` subject to `A x <= b`; `a` is `m x d` row-major.
    /// On `Optimal`, `self.x` holds the maximiser and the value is returned.
    pub fn maximize(&mut self, c: &[f64], a: &[f64], b: &[f64]) -> (LpStatus, f64) {
        let d = c.len();
        let m = b.len();
        debug_assert_eq!(a.len(), m * d);
        let ncol = m + d + 1; // y, artificials, rhs
        let last = ncol - 1;
        self.t.clear();
        self.t.resize(d * ncol, 0.0);
        self.obj.clear();
        self.obj.resize(ncol, 0.0);
        self.basis.clear();
        self.sign.clear();
        self.x.clear();
        self.x.resize(d, 0.0);
        let bscale = 1.0 + b.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        let cscale = 1.0 + c.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        for i in 0..d {
            let s = if c[i] < 0.0 { -1.0 } else { 1.0 };
            self.sign.push(s);
            let row = &mut self.t[i * ncol..(i + 1) * ncol];
            for j in 0..m {
                row[j] = s * a[j * d + i];
            }
            row[m + i] = 1.0;
            row[last] = s * c[i];
            self.basis.push(m + i);
        }
        // Phase 1: minimise the sum of artificials.
        for i in 0..d {
            for j in 0..ncol {
                if j >= m && j < m + d {
                    continue;
                }
                self.obj[j] -= self.t[i * ncol + j];
            }
        }
        let max_iter = 50 * (m + d) + 100;
        match self.iterate(d, m, ncol, m, 1e-12 * cscale, max_iter) {
            Ok(()) => {}
            Err(s) => return (s, 0.0),
        }
        if -self.obj[last] > 1e-9 * cscale {
            // The dual A'y = c, y >= 0 is infeasible: the primal is unbounded (or infeasible).
            return (LpStatus::Unbounded, 0.0);
        }
        // Drive artificials out of the basis where possible.
        for i in 0..d {
            if self.basis[i] >= m {
                let row = i * ncol;
                let mut best = None;
                let mut bv = PIV_TOL * 100.0;
                for j in 0..m {
                    let v = self.t[row + j].abs();
                    if v > bv {
                        bv = v;
                        best = Some(j);
                    }
                }
                if let Some(j) = best {
                    self.pivot(i, j, d, ncol);
                }
            }
        }
        // Phase 2: minimise b'y.
        for v in self.obj.iter_mut() {
            *v = 0.0;
        }
        self.obj[..m].copy_from_slice(b);
        for i in 0..d {
            let k = self.basis[i];
            let ck = if k < m { b[k] } else { 0.0 };
            if ck != 0.0 {
                for j in 0..ncol {
                    self.obj[j] -= ck * self.t[i * ncol + j];
                }
            }
        }
        match self.iterate(d, m, ncol, m, 1e-12 * bscale, max_iter) {
            Ok(()) => {}
            Err(LpStatus::Unbounded) => return (LpStatus::Infeasible, 0.0),
            Err(s) => return (s, 0.0),
        }
        for i in 0..d {
            self.x[i] = -self.obj[m + i] * self.sign[i];
        }
        (LpStatus::Optimal, -self.obj[last])
    }

    fn pivot(&mut self, r: usize, q: usize, d: usize, ncol: usize) {
        let _ = d;
        let (before, rest) = self.t.split_at_mut(r * ncol);
        let (prow, after) = rest.split_at_mut(ncol);
        let inv = 1.0 / prow[q];
        for v in prow.iter_mut() {
            *v *= inv;
        }
        prow[q] = 1.0;
        let prow: &[f64] = prow;
        let elim = |row: &mut [f64]| {
            let f = row[q];
            if f != 0.0 {
                for (x, &pv) in row.iter_mut().zip(prow) {
                    *x -= f * pv;
                }
                row[q] = 0.0;
            }
        };
        for row in before.chunks_exact_mut(ncol) {
            elim(row);
        }
        for row in after.chunks_exact_mut(ncol) {
            elim(row);
        }
        elim(&mut self.obj[..ncol]);
        self.basis[r] = q;
    }

    /// Simplex iterations over the first `nenter` columns.
    fn iterate(
        &mut self,
        d: usize,
        _m: usize,
        ncol: usize,
        nenter: usize,
        dj_tol: f64,
        max_iter: usize,
    ) -> Result<(), LpStatus> {
        let last = ncol - 1;
        let mut degenerate_run = 0usize;
        for _ in 0..max_iter {
            let bland = degenerate_run > 20;
            let mut q = None;
            let mut best = -dj_tol;
            for j in 0..nenter {
                let v = self.obj[j];
                if v < best {
                    q = Some(j);
                    if bland {
                        break;
                    }
                    best = v;
                }
            }
            let Some(q) = q else {
                return Ok(());
            };
            let mut r = None;
            let mut best_ratio = f64::INFINITY;
            let mut best_piv = 0.0;
            for i in 0..d {
                let a = self.t[i * ncol + q];
                if a > PIV_TOL {
                    let ratio = self.t[i * ncol + last].max(0.0) / a;
                    let better = if bland {
                        ratio < best_ratio - 1e-12
                            || (ratio <= best_ratio + 1e-12
                                && r.is_some_and(|rr: usize| self.basis[i] < self.basis[rr]))
                    } else {
                        ratio < best_ratio - 1e-12 || (ratio <= best_ratio + 1e-12 && a > best_piv)
                    };
                    if r.is_none() || better {
                        r = Some(i);
                        best_ratio = ratio;
                        best_piv = a;
                    }
                }
            }
            let Some(r) = r else {
                return Err(LpStatus::Unbounded);
            };
            if best_ratio <= 1e-14 {
                degenerate_run += 1;
            } else {
                degenerate_run = 0;
            }
            self.pivot(r, q, d, ncol);
        }
        Err(LpStatus::NotConverged)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_lp() {
        let mut ws = LpWorkspace::default();
        // max x + 2y s.t. 0 <= x <= 1, 0 <= y <= 3, x + y <= 3
        let a = [1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0, 1.0, 1.0];
        let b = [1.0, 0.0, 3.0, 0.0, 3.0];
        let (s, v) = ws.maximize(&[1.0, 2.0], &a, &b);
        assert_eq!(s, LpStatus::Optimal);
        assert!((v - 6.0).abs() < 1e-12);
        assert!((ws.x[0]).abs() < 1e-12 && (ws.x[1] - 3.0).abs() < 1e-12);
        // negative objective entries
        let (s, v) = ws.maximize(&[-1.0, -1.0], &a, &b);
        assert_eq!(s, LpStatus::Optimal);
        assert!(v.abs() < 1e-12);
    }

    #[test]
    fn infeasible_and_unbounded() {
        let mut ws = LpWorkspace::default();
        // x <= -1, -x <= -1 (x >= 1)
        let (s, _) = ws.maximize(&[1.0], &[1.0, -1.0], &[-1.0, -1.0]);
        assert_eq!(s, LpStatus::Infeasible);
        let (s, _) = ws.maximize(&[1.0], &[-1.0], &[0.0]);
        assert_eq!(s, LpStatus::Unbounded);
    }
}
