//! A small dense linear-programming solver (design time).
//!
//! `maximise c'x subject to A x <= b` with `x` free, started from a feasible
//! point `x0` that the caller supplies (every LP of the exploration and the
//! tree has one at hand: a region's centre, or any point with a free
//! "smallest slack" variable set to the smallest slack). The method is the
//! primal active-set form of the simplex method: move along the projection
//! of `c` onto the null space of the working constraints until a
//! constraint blocks (it joins the working set); at a point where `c` lies
//! in their span, drop a constraint with a negative multiplier, or stop
//! (all multipliers non-negative: optimal). The working rows are kept as an
//! orthonormal basis (modified Gram-Schmidt, rebuilt from the original rows
//! after every drop), so every step is computed from the problem data
//! rather than from a long chain of tableau updates: the answer is exact up
//! to a few rounding errors however many pivots it took, and optimality is
//! certified by the multipliers. Bland's rule after a run of degenerate
//! steps rules out cycling. A previous two-phase tableau simplex on the
//! dual could return "optimal" with a wrong dual after an ill-conditioned
//! pivot, which made the search tree drop regions from cells they meet.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

/// Outcome of an LP solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LpStatus {
    /// An optimum was found.
    Optimal,
    /// The objective is unbounded above.
    Unbounded,
    /// The iteration limit was hit (or the start point was not finite).
    NotConverged,
}

/// Caller-owned workspace of the LP solver (reused across solves).
#[derive(Default, Debug)]
pub(crate) struct LpWorkspace {
    /// Orthonormal basis of the working rows, `k x d` row-major.
    q: Vec<f64>,
    /// `R` with `a_{W[j]} = sum_i R[i][j] q_i`, stored `k_max x k_max`.
    r: Vec<f64>,
    work: Vec<usize>,
    in_work: Vec<bool>,
    dir: Vec<f64>,
    qc: Vec<f64>,
    lam: Vec<f64>,
    anorm: Vec<f64>,
    slack: Vec<f64>,
    ad: Vec<f64>,
    v: Vec<f64>,
    coef: Vec<f64>,
    /// Rows with at most two non-zeros (box rows, the radius bound):
    /// `(count, [column; 2], [value; 2])`, count 3 meaning dense.
    sparse: Vec<(u8, [usize; 2], [f64; 2])>,
    /// Working rows to push again after a drop.
    redo: Vec<usize>,
    /// The maximiser of the last optimal solve.
    pub x: Vec<f64>,
    /// Iterations of the last solve.
    pub iterations: usize,
}

/// Dot product with four independent partial sums: the adds of a plain
/// `sum()` form one dependent chain (four cycles each), which made the
/// short (length 9 to 10) products of the LPs latency-bound.
#[inline]
pub(crate) fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let (xr, yr) = (xc.remainder(), yc.remainder());
    let mut acc = [0.0f64; 4];
    for (u, v) in xc.zip(yc) {
        for t in 0..4 {
            acc[t] += u[t] * v[t];
        }
    }
    let mut s = (acc[0] + acc[2]) + (acc[1] + acc[3]);
    for (u, v) in xr.iter().zip(yr) {
        s += u * v;
    }
    s
}

/// The plain sequential dot product (one rounding order, as every solve
/// used before the fast mode existed).
#[inline]
fn dot_seq(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

/// [`dot`] in the fast mode, [`dot_seq`] otherwise.
#[inline]
fn dotk<const FAST: bool>(x: &[f64], y: &[f64]) -> f64 {
    if FAST { dot(x, y) } else { dot_seq(x, y) }
}

impl LpWorkspace {
    /// Appends row `a_i` to the orthonormal basis; false if it is (numerically) dependent.
    fn push_row<const FAST: bool>(&mut self, a: &[f64], i: usize, d: usize) -> bool {
        let k = self.work.len();
        let row = &a[i * d..(i + 1) * d];
        let mut v = std::mem::take(&mut self.v);
        let mut coef = std::mem::take(&mut self.coef);
        v.clear();
        v.extend_from_slice(row);
        coef.clear();
        coef.resize(k, 0.0);
        // Modified Gram-Schmidt, a second pass for orthogonality to working
        // precision when the first one cancelled much of the row (the
        // "twice is enough" criterion of Daniel, Gragg, Kaufman and Stewart:
        // a row that keeps more than 1/sqrt(2) of its norm is orthogonal to
        // working precision after one pass).
        for pass in 0..2 {
            for j in 0..k {
                let qj = &self.q[j * d..(j + 1) * d];
                let s = dotk::<FAST>(qj, &v);
                coef[j] += s;
                for t in 0..d {
                    v[t] -= s * qj[t];
                }
            }
            if pass == 0 && (k == 0 || (FAST && dot(&v, &v) > 0.5 * self.anorm[i] * self.anorm[i]))
            {
                break;
            }
        }
        let nv = dotk::<FAST>(&v, &v).sqrt();
        if nv <= 1e-12 * self.anorm[i] {
            self.v = v;
            self.coef = coef;
            return false;
        }
        for t in 0..d {
            v[t] /= nv;
        }
        self.q.extend_from_slice(&v);
        // R is d x d, column k gets the coefficients.
        for j in 0..k {
            self.r[j * d + k] = coef[j];
        }
        self.r[k * d + k] = nv;
        for j in k + 1..d {
            self.r[j * d + k] = 0.0;
        }
        self.v = v;
        self.coef = coef;
        self.work.push(i);
        self.in_work[i] = true;
        true
    }

    /// Rebuilds the basis after the working row at position `from` was
    /// removed. Modified Gram-Schmidt is sequential: the basis vectors and
    /// `R` columns of the rows before `from` are exactly those a rebuild
    /// from scratch computes, so only the later rows are pushed again.
    fn rebuild<const FAST: bool>(&mut self, a: &[f64], d: usize, from: usize) {
        let mut rows = std::mem::take(&mut self.redo);
        rows.clear();
        rows.extend_from_slice(&self.work[from.min(self.work.len())..]);
        self.work.truncate(from);
        self.q.truncate(from * d);
        for &i in &rows {
            self.in_work[i] = false;
        }
        for &i in &rows {
            let _ = self.push_row::<FAST>(a, i, d);
        }
        self.redo = rows;
    }

    /// maximise `c'x` subject to `A x <= b` (`a` is `m x d` row-major),
    /// starting from `x0`, which must satisfy the constraints (up to
    /// rounding). On `Optimal`, `self.x` holds the maximiser and the value
    /// is returned.
    pub fn maximize_from(
        &mut self,
        c: &[f64],
        a: &[f64],
        b: &[f64],
        x0: &[f64],
    ) -> (LpStatus, f64) {
        self.maximize_warm(c, a, b, x0, &[])
    }

    /// [`Self::maximize_from`] with a warm working set: the rows of `warm`
    /// that are active at `x0` (and independent) start in the working set,
    /// so a start at the optimal vertex of a similar LP needs few steps.
    pub fn maximize_warm(
        &mut self,
        c: &[f64],
        a: &[f64],
        b: &[f64],
        x0: &[f64],
        warm: &[usize],
    ) -> (LpStatus, f64) {
        self.maximize_inner::<false>(c, a, b, x0, warm, f64::INFINITY)
    }

    /// Decides whether `max c'x` over `A x <= b` exceeds `level`, stopping
    /// as soon as a vertex on the way does: on `Optimal` with a value above
    /// `level`, `self.x` is a feasible point with that value (not
    /// necessarily a maximiser); with a value at or below `level` it is the
    /// maximiser, as from [`Self::maximize_from`]. The redundancy test only
    /// needs a feasible point beyond the row, and the simplex path crosses
    /// the level well before it reaches the optimum (the row's LP is capped
    /// far beyond it).
    pub fn maximize_until(
        &mut self,
        c: &[f64],
        a: &[f64],
        b: &[f64],
        x0: &[f64],
        level: f64,
    ) -> (LpStatus, f64) {
        self.maximize_inner::<true>(c, a, b, x0, &[], level)
    }

    fn maximize_inner<const FAST: bool>(
        &mut self,
        c: &[f64],
        a: &[f64],
        b: &[f64],
        x0: &[f64],
        warm: &[usize],
        level: f64,
    ) -> (LpStatus, f64) {
        let d = c.len();
        let m = b.len();
        debug_assert_eq!(a.len(), m * d);
        debug_assert_eq!(x0.len(), d);
        self.x.clear();
        self.x.extend_from_slice(x0);
        self.iterations = 0;
        if !x0.iter().all(|v| v.is_finite()) {
            return (LpStatus::NotConverged, 0.0);
        }
        self.q.clear();
        self.r.clear();
        self.r.resize(d * d, 0.0);
        self.work.clear();
        self.in_work.clear();
        self.in_work.resize(m, false);
        // One pass over the rows: norms, sparsity, slacks at the start.
        self.anorm.resize(m, 0.0);
        self.sparse.resize(m, (0, [0; 2], [0.0; 2]));
        self.slack.resize(m, 0.0);
        self.dir.clear();
        self.dir.resize(d, 0.0);
        let rows = a.chunks_exact(d).zip(b);
        let outs = self
            .anorm
            .iter_mut()
            .zip(&mut self.sparse)
            .zip(&mut self.slack);
        for ((row, bi), ((nrm, sp), sl)) in rows.zip(outs) {
            *nrm = dotk::<FAST>(row, row).sqrt();
            *sl = bi - dotk::<FAST>(row, x0);
            *sp = (0u8, [0usize; 2], [0.0; 2]);
            for (t, &v) in row.iter().enumerate() {
                if v != 0.0 {
                    if sp.0 == 2 {
                        sp.0 = 3;
                        break;
                    }
                    sp.1[sp.0 as usize] = t;
                    sp.2[sp.0 as usize] = v;
                    sp.0 += 1;
                }
            }
        }
        self.ad.clear();
        self.ad.resize(m, 0.0);
        let cn = dotk::<FAST>(c, c).sqrt();
        if cn == 0.0 {
            return (LpStatus::Optimal, 0.0);
        }
        for &i in warm {
            if i < m
                && !self.in_work[i]
                && self.work.len() < d
                && self.slack[i].abs() <= 1e-10 * (1.0 + b[i].abs())
            {
                let _ = self.push_row::<FAST>(a, i, d);
            }
        }
        let max_iter = 10 * (m + d) + 100;
        let mut degenerate_run = 0usize;
        // Working rows the direction `dir` is orthogonal to (usize::MAX: recompute).
        let mut projected = usize::MAX;
        for _ in 0..max_iter {
            self.iterations += 1;
            let bland = degenerate_run > 2 * d + 5;
            let k = self.work.len();
            if FAST && projected != usize::MAX && projected + 1 == k {
                // One row joined since the last step: project it out of the
                // direction (twice, as below), extend qc.
                let qj = &self.q[(k - 1) * d..k * d];
                self.qc.push(dot(qj, c));
                for _ in 0..2 {
                    let s = dot(qj, &self.dir);
                    for t in 0..d {
                        self.dir[t] -= s * qj[t];
                    }
                }
            } else {
                // qc = Q c, dir = c - Q'qc.
                self.qc.clear();
                self.dir.copy_from_slice(c);
                for j in 0..k {
                    let qj = &self.q[j * d..(j + 1) * d];
                    let s = dotk::<FAST>(qj, c);
                    self.qc.push(s);
                    for t in 0..d {
                        self.dir[t] -= s * qj[t];
                    }
                }
                // Re-orthogonalise the direction once (it must lie in the null space).
                for j in 0..k {
                    let qj = &self.q[j * d..(j + 1) * d];
                    let s = dotk::<FAST>(qj, &self.dir);
                    for t in 0..d {
                        self.dir[t] -= s * qj[t];
                    }
                }
            }
            projected = k;
            let dn = dotk::<FAST>(&self.dir, &self.dir).sqrt();
            if k < d && dn > 1e-11 * cn {
                // Ratio test along dir.
                let mut best: Option<usize> = None;
                let mut tmin = f64::INFINITY;
                let mut best_ad = 0.0;
                for i in 0..m {
                    // Rows with at most two non-zeros: the same value as the
                    // dense product (adding exact zeros does not round).
                    let ad = match self.sparse[i] {
                        (0, _, _) => 0.0,
                        (1, [j, _], [v, _]) => v * self.dir[j],
                        (2, [j, l], [v, w]) => v * self.dir[j] + w * self.dir[l],
                        _ => dotk::<FAST>(&a[i * d..(i + 1) * d], &self.dir),
                    };
                    self.ad[i] = ad;
                    if self.in_work[i] || ad <= 1e-11 * dn * self.anorm[i] {
                        continue;
                    }
                    let slack = self.slack[i].max(0.0);
                    let t = slack / ad;
                    let better = match best {
                        None => true,
                        Some(_) if bland => t < tmin * (1.0 - 1e-12) - 1e-300,
                        Some(_) => {
                            t < tmin * (1.0 - 1e-12) - 1e-300
                                || (t <= tmin * (1.0 + 1e-12) + 1e-300
                                    && ad / self.anorm[i] > best_ad)
                        }
                    };
                    if better {
                        best = Some(i);
                        tmin = t;
                        best_ad = ad / self.anorm[i];
                    }
                }
                let Some(i) = best else {
                    return (LpStatus::Unbounded, f64::INFINITY);
                };
                for t in 0..d {
                    self.x[t] += tmin * self.dir[t];
                }
                for (s, ad) in self.slack.iter_mut().zip(&self.ad) {
                    *s -= tmin * ad;
                }
                self.slack[i] = 0.0;
                if level < f64::INFINITY {
                    let v = dot(c, &self.x);
                    if v > level {
                        return (LpStatus::Optimal, v);
                    }
                }
                if tmin * dn <= 1e-14 * (1.0 + dotk::<FAST>(&self.x, &self.x).sqrt()) {
                    degenerate_run += 1;
                } else {
                    degenerate_run = 0;
                }
                if !self.push_row::<FAST>(a, i, d) {
                    // Cannot happen in exact arithmetic (a_i'dir > 0 with dir in
                    // the null space of the working rows); give up safely.
                    return (LpStatus::NotConverged, 0.0);
                }
                continue;
            }
            // c lies in the span of the working rows: multipliers R lam = qc.
            self.lam.clear();
            self.lam.resize(k, 0.0);
            for j in (0..k).rev() {
                let mut s = self.qc[j];
                for t in j + 1..k {
                    s -= self.r[j * d + t] * self.lam[t];
                }
                self.lam[j] = s / self.r[j * d + j];
            }
            let mut drop: Option<usize> = None;
            let mut most = -1e-11 * cn;
            for j in 0..k {
                let v = self.lam[j] * self.anorm[self.work[j]];
                if v < -1e-11 * cn {
                    let pick = match drop {
                        None => true,
                        Some(o) if bland => self.work[j] < self.work[o],
                        Some(_) => v < most,
                    };
                    if pick {
                        drop = Some(j);
                        most = v;
                    }
                }
            }
            let Some(j) = drop else {
                return (LpStatus::Optimal, dotk::<FAST>(c, &self.x));
            };
            let i = self.work.remove(j);
            self.in_work[i] = false;
            self.rebuild::<FAST>(a, d, j);
            projected = usize::MAX;
        }
        (LpStatus::NotConverged, 0.0)
    }
}

/// A feasible start for an LP with a free "smallest slack" variable in
/// column `rcol`: `x` given except `x[rcol]`, which is set to the largest
/// value every row allows (rows without that variable must already hold).
pub(crate) fn slack_start(a: &[f64], b: &[f64], x: &mut [f64], rcol: usize) {
    let d = x.len();
    x[rcol] = 0.0;
    let mut r = f64::INFINITY;
    for i in 0..b.len() {
        let row = &a[i * d..(i + 1) * d];
        let coef = row[rcol];
        if coef > 0.0 {
            r = r.min((b[i] - dot_seq(row, x)) / coef);
        }
    }
    x[rcol] = if r.is_finite() { r } else { 0.0 };
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
        let (s, v) = ws.maximize_from(&[1.0, 2.0], &a, &b, &[0.5, 0.5]);
        assert_eq!(s, LpStatus::Optimal);
        assert!((v - 6.0).abs() < 1e-12);
        assert!((ws.x[0]).abs() < 1e-12 && (ws.x[1] - 3.0).abs() < 1e-12);
        // negative objective entries, degenerate start at a vertex
        let (s, v) = ws.maximize_from(&[-1.0, -1.0], &a, &b, &[1.0, 0.0]);
        assert_eq!(s, LpStatus::Optimal);
        assert!(v.abs() < 1e-12);
    }

    /// `maximize_until` against the full solve on random 6-D LPs (box plus
    /// random rows, some with one or two non-zeros): below the optimum it
    /// returns a feasible point beyond the level, at or above it the
    /// optimum itself.
    #[test]
    fn until_decides_like_the_full_solve() {
        let mut rng = crate::rng::Rng::new(9);
        let mut ws = LpWorkspace::default();
        let d = 6;
        let (mut beyond, mut below) = (0, 0);
        for _ in 0..400 {
            let m = 4 + (rng.next_u64() % 20) as usize;
            let mut a = Vec::new();
            let mut b = Vec::new();
            for _ in 0..m {
                let nz = 1 + (rng.next_u64() % d as u64) as usize;
                let row: Vec<f64> = (0..d)
                    .map(|j| if j < nz { rng.sym() } else { 0.0 })
                    .collect();
                a.extend(row);
                b.push(0.5 + rng.sym().abs());
            }
            for j in 0..d {
                for s in [1.0, -1.0] {
                    a.extend((0..d).map(|t| if t == j { s } else { 0.0 }));
                    b.push(3.0);
                }
            }
            let c: Vec<f64> = (0..d).map(|_| rng.sym()).collect();
            let x0 = vec![0.0; d];
            let (s, opt) = ws.maximize_from(&c, &a, &b, &x0);
            assert_eq!(s, LpStatus::Optimal);
            let level = opt * (0.5 + rng.sym().abs()) + 0.1 * rng.sym();
            let (s, v) = ws.maximize_until(&c, &a, &b, &x0, level);
            assert_eq!(s, LpStatus::Optimal);
            if v > level {
                beyond += 1;
                assert!(opt > level && v <= opt + 1e-9, "{v} {opt} {level}");
                assert!((dot(&c, &ws.x) - v).abs() < 1e-12);
                for i in 0..b.len() {
                    assert!(dot(&a[i * d..(i + 1) * d], &ws.x) <= b[i] + 1e-9);
                }
            } else {
                below += 1;
                assert!((v - opt).abs() < 1e-9, "{v} {opt}");
                assert!(opt <= level + 1e-9);
            }
        }
        assert!(beyond > 50 && below > 50, "{beyond} {below}");
    }

    #[test]
    fn unbounded() {
        let mut ws = LpWorkspace::default();
        let (s, _) = ws.maximize_from(&[1.0], &[-1.0], &[0.0], &[1.0]);
        assert_eq!(s, LpStatus::Unbounded);
    }

    /// Random LPs against the vertex enumeration in 2-D and the optimality
    /// certificate in 6-D: the value equals b'y for the recovered dual.
    #[test]
    fn random_lps_match_vertex_enumeration() {
        let mut rng = crate::rng::Rng::new(5);
        let mut ws = LpWorkspace::default();
        for _ in 0..300 {
            let m = 3 + (rng.next_u64() % 12) as usize;
            let mut a = Vec::new();
            let mut b = Vec::new();
            for _ in 0..m {
                let (u, v) = (rng.sym(), rng.sym());
                a.extend([u, v]);
                b.push(1.0 + rng.sym().abs());
            }
            // bounded: a box
            a.extend([1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0]);
            b.extend([5.0, 5.0, 5.0, 5.0]);
            let c = [rng.sym(), rng.sym()];
            let (s, v) = ws.maximize_from(&c, &a, &b, &[0.0, 0.0]);
            assert_eq!(s, LpStatus::Optimal);
            // Vertex enumeration.
            let mm = b.len();
            let mut best = f64::NEG_INFINITY;
            for i in 0..mm {
                for j in i + 1..mm {
                    let (a1, a2, a3, a4) = (a[2 * i], a[2 * i + 1], a[2 * j], a[2 * j + 1]);
                    let det = a1 * a4 - a2 * a3;
                    if det.abs() < 1e-12 {
                        continue;
                    }
                    let x = (b[i] * a4 - a2 * b[j]) / det;
                    let y = (a1 * b[j] - b[i] * a3) / det;
                    if (0..mm).all(|k| a[2 * k] * x + a[2 * k + 1] * y <= b[k] + 1e-9) {
                        best = best.max(c[0] * x + c[1] * y);
                    }
                }
            }
            assert!((v - best).abs() < 1e-9, "{v} vs {best}");
        }
    }
}
