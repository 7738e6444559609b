//! The iterations of the dual active-set method on a set-up
//! [`QpSolver`]: the dual-feasible add of the most violated constraint, the
//! dual step that removes a blocking one, the step along the null vector
//! when an entering constraint is dependent, and the LDL' updates of `M =
//! G_A H^-1 G_A'` for each (in `z` itself, see the `solver` module).

use crate::solver::{QpScalar, QpSolver, Slots, check_len, dot};
use crate::{QpData, QpError, SolveInfo, Start};

impl<S: QpScalar> QpSolver<'_, S> {
    /// Solves `min 1/2 z'Hz + q'z` s.t. `l <= G z <= u`, `lb <= z <= ub`
    /// from `start`; read the result with [`QpSolver::solution`],
    /// [`QpSolver::multipliers`] and [`QpSolver::active_set`].
    ///
    /// Each iteration adds the most violated constraint (when the current
    /// multipliers are dual feasible) or removes the constraint that
    /// blocks the dual step; the LDL' factor of the active constraints is
    /// updated in `O(n k + k^2)` for `k` active constraints, never
    /// recomputed.
    pub fn solve(&mut self, data: &QpData<'_, S>, start: Start) -> Result<SolveInfo, QpError> {
        let (n, m) = (self.n, self.m);
        check_len(n, data.q.len())?;
        check_len(m, data.l.len())?;
        check_len(m, data.u.len())?;
        check_len(n, data.lb.len())?;
        check_len(n, data.ub.len())?;
        if !data.q.iter().all(|v| v.is_finite()) {
            return Err(QpError::NonFinite);
        }
        for (lo, hi) in data.l.iter().zip(data.u).chain(data.lb.iter().zip(data.ub)) {
            if lo > hi {
                return Err(QpError::InvalidBounds);
            }
            // NaN compares false both ways.
            if lo.partial_cmp(hi).is_none() {
                return Err(QpError::NonFinite);
            }
        }
        // z_unc = -H^-1 q.
        for (zu, row) in self.zunc.iter_mut().zip(self.hinv.chunks_exact(n.max(1))) {
            *zu = -dot(row, data.q);
        }
        match start {
            Start::Cold => self.clear(),
            Start::Warm => self.refactor(data),
        }
        let mut iterations = 0;
        loop {
            if self.count > 0 && self.df.at(self.count - 1) == S::ZERO {
                if iterations >= self.settings.max_iterations {
                    return Err(QpError::IterationLimit);
                }
                self.singular_step()?;
            } else {
                self.solve_mustar();
                match self.blocking_dual() {
                    None => {
                        for (mu, &ms) in self.mu.iter_mut().zip(self.mustar.iter()).take(self.count)
                        {
                            *mu = ms;
                        }
                        self.primal();
                        match self.most_violated(data) {
                            None => {
                                return Ok(SolveInfo {
                                    iterations,
                                    active: self.count,
                                });
                            }
                            Some((j, side)) => {
                                if iterations >= self.settings.max_iterations {
                                    return Err(QpError::IterationLimit);
                                }
                                if self.count > self.n {
                                    return Err(QpError::Infeasible);
                                }
                                let (lo, hi) = Self::bounds(data, m, j);
                                self.add(j, side, if side & 1 == 1 { hi } else { lo });
                            }
                        }
                    }
                    Some((p, alpha)) => {
                        if iterations >= self.settings.max_iterations {
                            return Err(QpError::IterationLimit);
                        }
                        for (mu, &ms) in self.mu.iter_mut().zip(self.mustar.iter()).take(self.count)
                        {
                            *mu = mu.mul_add(alpha, ms - *mu);
                        }
                        self.remove(p);
                    }
                }
            }
            iterations += 1;
        }
    }

    /// Two steps of iterative refinement of the last successful solve on
    /// its final active set: the active constraints' residual `r = G_A z -
    /// b_A` (as computed from `z`, not as the iteration's cancellation
    /// left it), `M d = r` through the kept LDL' factor, `z -= H^-1 G_A'
    /// d`, `mu += d`. On an ill-conditioned `H` the iterate `z = z_unc -
    /// sum w_p mu_p` cancels large terms and can miss the active
    /// constraints by about `eps cond(H) |z_unc|`: at `cond(H)` 1.8e11
    /// (tests/qp_mpc.rs) the solve is 2e-5 from clarabel's solution
    /// (relative), refined 1.7e-7.
    /// `O(n k + k^2)` per step; not part of [`QpSolver::solve`] (nor of its
    /// certified counts), for callers that can afford it. Call it after a
    /// successful solve with the same data.
    pub fn refine(&mut self, data: &QpData<'_, S>) -> Result<(), QpError> {
        let (n, m) = (self.n, self.m);
        check_len(m, data.l.len())?;
        check_len(m, data.u.len())?;
        check_len(n, data.lb.len())?;
        check_len(n, data.ub.len())?;
        let c = n + 1;
        let k = self.count.min(self.tmp.len());
        if (0..k).any(|p| self.df.at(p) == S::ZERO) {
            return Ok(());
        }
        for _ in 0..2 {
            for p in 0..k {
                let j = self.active.at(p);
                let (lo, hi) = Self::bounds(data, m, j);
                let b = if self.side.at(p) & 1 == 1 { hi } else { lo };
                let r = self.value(j, self.z) - b;
                self.tmp.put(p, r);
            }
            // L y = r, then D^-1, then L' d = y.
            for i in 0..k {
                let row = self.lf.get(i * c..i * c + i).unwrap_or(&[]);
                let (done, rest) = self.tmp.split_at_mut(i);
                let v = rest.at(0) - dot(row, done);
                rest.put(0, v);
            }
            for (t, &d) in self.tmp.iter_mut().zip(self.df.iter()).take(k) {
                *t = *t / d;
            }
            let (head, _) = self.tmp.split_at_mut(k);
            back_substitute(self.lf, c, head);
            for p in 0..k {
                let d = self.tmp.at(p);
                let j = self.active.at(p);
                // `wvec(j)` by fields, as in `primal` (and for its reason).
                let w = if j < m {
                    self.w.get(j * n..(j + 1) * n)
                } else {
                    self.hinv.get((j - m) * n..(j - m + 1) * n)
                };
                for (zi, &wi) in self.z.iter_mut().zip(w.unwrap_or(&[])) {
                    *zi -= wi * d;
                }
                let mu = self.mu.at(p) + d;
                self.mu.put(p, mu);
            }
        }
        Ok(())
    }

    /// Rebuilds the factor of the stored active set, dropping constraints
    /// that are dependent or whose active bound is infinite.
    fn refactor(&mut self, data: &QpData<'_, S>) {
        let k = self.count;
        self.clear();
        // The index list below `k` is intact (`clear` resets `pos`, `count`).
        for t in 0..k {
            if self.count > self.n {
                break;
            }
            let j = self.active.at(t);
            let s = self.side.at(t);
            let (lo, hi) = Self::bounds(data, self.m, j);
            let bound = if s == 1 { hi } else { lo };
            if !bound.is_finite() || self.pos.at(j) != 0 {
                continue;
            }
            // Writes position `count <= t`: entries not yet read survive.
            let code = (s & 1) + if lo == hi { 2 } else { 0 };
            self.add(j, code, bound);
            if self.count > 0 && self.df.at(self.count - 1) == S::ZERO {
                self.count -= 1;
                self.pos.put(j, 0);
            }
        }
    }

    /// `mustar = M^-1 (G_A z_unc - b_A)` through the LDL' factor. The
    /// right-hand side is fixed during a solve and the forward solve
    /// `L^-1 rhs` of the positions the last changes left alone is kept, so
    /// only the positions from the first changed one are redone.
    fn solve_mustar(&mut self) {
        let k = self.count;
        let c = self.n + 1;
        let first = self.fwd_valid.min(k);
        // The rows of L by stepping through them, not at `i * c`: the pinned
        // AVR nightly miscompiled that multiply (docs/avr-qp.md, bug 2).
        for (i, row) in self.lf.chunks(c.max(1)).enumerate().take(k) {
            if i >= first {
                let (done, _) = self.fwd.split_at(i.min(self.fwd.len()));
                let v = self.rhs.at(i) - dot(row.get(..i).unwrap_or(&[]), done);
                self.fwd.put(i, v);
            }
        }
        self.fwd_valid = k;
        let pairs = self.fwd.iter().zip(self.df.iter());
        for (ms, (&f, &d)) in self.mustar.iter_mut().zip(pairs).take(k) {
            *ms = f / d;
        }
        let k = k.min(self.mustar.len());
        let (head, _) = self.mustar.split_at_mut(k);
        back_substitute(self.lf, c, head);
    }

    /// Whether `mu + a (mustar - mu)` must stop short at `a < 1` (or 1) to
    /// keep the multipliers' signs; the blocking position and the step.
    fn blocking_dual(&self) -> Option<(usize, S)> {
        let mut best: Option<(usize, S)> = None;
        for p in 0..self.count {
            if self.is_equality(p) {
                continue;
            }
            let sgn = if self.side.at(p) & 1 == 1 {
                S::ONE
            } else {
                -S::ONE
            };
            let star = sgn * self.mustar.at(p);
            if star < -self.dtol {
                let cur = sgn * self.mu.at(p);
                let alpha = cur / (cur - star);
                if best.is_none_or(|(_, a)| alpha < a) {
                    best = Some((p, alpha));
                }
            }
        }
        best
    }

    /// An equality row (`l = u`) keeps its multiplier of either sign.
    /// Side codes: bit 0 the side (1 upper), bit 1 an equality row.
    fn is_equality(&self, p: usize) -> bool {
        self.side.at(p) >= 2
    }

    /// `z = z_unc - H^-1 G_A' mu`.
    fn primal(&mut self) {
        for (z, &zu) in self.z.iter_mut().zip(self.zunc.iter()) {
            *z = zu;
        }
        let (n, m) = (self.n, self.m);
        for p in 0..self.count {
            let mu = self.mu.at(p);
            let j = self.active.at(p);
            // `wvec(j)`, borrowing the fields alone (z is written). A shared
            // helper for both was tried: its inlining into the firmware's
            // `QpLaw::control` met the pinned nightly's AVR bug 2.
            let w = if j < m {
                self.w.get(j * n..(j + 1) * n)
            } else {
                self.hinv.get((j - m) * n..(j - m + 1) * n)
            };
            for (zi, &wi) in self.z.iter_mut().zip(w.unwrap_or(&[])) {
                *zi -= wi * mu;
            }
        }
    }

    /// The inactive constraint violated most (beyond `primal_tol`) at `z`:
    /// rows `g_j' z` (`O(n)` each), then bounds (`z_i` itself).
    fn most_violated(&self, data: &QpData<'_, S>) -> Option<(usize, usize)> {
        let mut best: Option<(usize, usize, S)> = None;
        let mut consider = |j: usize, v: S, lo: S, hi: S| {
            let (viol, side) = if v - hi > lo - v {
                (v - hi, 1)
            } else {
                (lo - v, 0)
            };
            let side = side + if lo == hi { 2 } else { 0 };
            if viol > self.ptol && best.is_none_or(|(_, _, b)| viol > b) {
                best = Some((j, side, viol));
            }
        };
        let (n, m) = (self.n, self.m);
        let rows = self.g.chunks_exact(n.max(1)).zip(data.l.iter().zip(data.u));
        let (pos_rows, pos_bounds) = self.pos.split_at(m.min(self.pos.len()));
        for (j, ((gj, (&lo, &hi)), &p)) in rows.zip(pos_rows).enumerate() {
            if p == 0 {
                consider(j, dot(gj, self.z), lo, hi);
            }
        }
        let bounds = self.z.iter().zip(data.lb.iter().zip(data.ub));
        for (i, ((&v, (&lo, &hi)), &p)) in bounds.zip(pos_bounds).enumerate() {
            if p == 0 {
                consider(m + i, v, lo, hi);
            }
        }
        best.map(|(j, s, _)| (j, s))
    }

    /// Appends constraint `j` (side code: bit 0 upper, bit 1 equality; its
    /// active bound `b`) to the active set and its row to the LDL' factor:
    /// the new row of `M` is `O(k)` entries of `H^-1` (`O(n k)` for rows
    /// against rows), the forward solve `O(k^2)`. A dependent constraint
    /// gets the pivot 0 (resolved by [`Self::singular_step`]).
    fn add(&mut self, j: usize, code: usize, b: S) {
        let c = self.n + 1;
        let k = self.count;
        let diag = self.m_entry(j, j);
        for p in 0..k {
            let v = self.m_entry(self.active.at(p), j);
            self.tmp.put(p, v);
        }
        // Forward solve L t = c, then L_new = t / d, d_new = diag - t' D^-1 t.
        let mut d = diag;
        for i in 0..k {
            let row = self.lf.get(i * c..i * c + i).unwrap_or(&[]);
            let v = self.tmp.at(i) - dot(row, self.tmp.get(..i).unwrap_or(&[]));
            self.tmp.put(i, v);
            let l = v / self.df.at(i);
            self.lf.put(k * c + i, l);
            d -= l * v;
        }
        self.lf.put(k * c + k, S::ONE);
        // With `n` independent constraints active they span every
        // direction, so the entering one depends on them whatever the
        // rounding of `d` (in f32 on ill-conditioned problems the rounding
        // passed the test: docs/qp.md, "Problems beyond the tricopter's").
        self.df.put(
            k,
            if k < self.n && d > self.pivtol * diag {
                d
            } else {
                S::ZERO
            },
        );
        let r = self.value(j, self.zunc) - b;
        self.rhs.put(k, r);
        self.active.put(k, j);
        self.side.put(k, code);
        self.pos.put(j, k + 1);
        self.mu.put(k, S::ZERO);
        self.count = k + 1;
    }

    /// Removes position `p` from the active set: deletes its row and column
    /// of the factor and restores the trailing block by a rank-one update
    /// `+ d_p l_p l_p'` (Gill, Golub, Murray, Saunders): `O(k^2)`.
    fn remove(&mut self, p: usize) {
        let c = self.n + 1;
        let k = self.count;
        // `p` is an active position (the callers'); the guard also keeps
        // `k - 1` from wrapping.
        if p >= k {
            return;
        }
        // Row offsets by additions, no `r * c`: with this function's frame
        // the pinned nightly miscompiled such a multiply on the AVR (bug 2
        // of docs/avr-qp.md, found by the HIL's scan).
        let mut row_p = 0;
        for _ in 0..p {
            row_p += c;
        }
        let mut alpha = self.df.at(p);
        let mut at = row_p + c + p;
        for r in p + 1..k {
            let v = self.lf.at(at);
            self.wv.put(r, v);
            at += c;
        }
        self.pos.put(self.active.at(p), 0);
        // Shift rows and columns after p up and left by one.
        let mut row = row_p;
        for r in p..k - 1 {
            let next = row + c;
            for col in 0..p {
                let v = self.lf.at(next + col);
                self.lf.put(row + col, v);
            }
            for col in p..=r {
                let v = self.lf.at(next + col + 1);
                self.lf.put(row + col, v);
            }
            let (df, mu, rhs, wv) = (
                self.df.at(r + 1),
                self.mu.at(r + 1),
                self.rhs.at(r + 1),
                self.wv.at(r + 1),
            );
            self.df.put(r, df);
            self.mu.put(r, mu);
            self.rhs.put(r, rhs);
            self.wv.put(r, wv);
            let (j, side) = (self.active.at(r + 1), self.side.at(r + 1));
            self.active.put(r, j);
            self.side.put(r, side);
            self.pos.put(j, r + 1);
            row = next;
        }
        self.count = k - 1;
        self.fwd_valid = self.fwd_valid.min(p);
        // Rank-one update of rows/columns p.. with alpha * w w'.
        let mut below = row_p + c;
        for i in p..k - 1 {
            let pv = self.wv.at(i);
            let di = self.df.at(i);
            let dnew = di + alpha * pv * pv;
            if dnew != S::ZERO {
                let beta = pv * alpha / dnew;
                alpha = di * alpha / dnew;
                self.df.put(i, dnew);
                let mut at = below + i;
                for r in i + 1..k - 1 {
                    let l = self.lf.at(at);
                    let w = self.wv.at(r) - pv * l;
                    self.wv.put(r, w);
                    self.lf.put(at, l.mul_add(beta, w));
                    at += c;
                }
            }
            below += c;
        }
    }

    /// The last active constraint is a combination of the others: move the
    /// multipliers along the null vector of `M` (the primal point does not
    /// change) until one of the others reaches zero, and remove it; if none
    /// does, the dual is unbounded and the QP infeasible.
    fn singular_step(&mut self) -> Result<(), QpError> {
        let c = self.n + 1;
        let k = self.count.min(self.tmp.len());
        // Called with a dependent last constraint, so `k >= 1`.
        let Some(last) = k.checked_sub(1) else {
            return Err(QpError::Infeasible);
        };
        // p = L^-T e_last.
        let (head, _) = self.tmp.split_at_mut(k);
        head.fill(S::ZERO);
        head.put(last, S::ONE);
        back_substitute(self.lf, c, head);
        let sk = if self.side.at(last) & 1 == 0 {
            -S::ONE
        } else {
            S::ONE
        };
        // A rate counts as negative beyond the null vector's rounding: an
        // entry that is zero in exact arithmetic (a bound the dependent
        // row does not involve) would otherwise block at a step of 1e15.
        let mut pmax = S::ZERO;
        for &t in self.tmp.iter().take(k) {
            let a = if t < S::ZERO { -t } else { t };
            if a > pmax {
                pmax = a;
            }
        }
        let floor = self.dtol * pmax;
        let mut best: Option<(usize, S)> = None;
        for i in 0..last {
            if self.is_equality(i) {
                continue;
            }
            let si = if self.side.at(i) & 1 == 1 {
                S::ONE
            } else {
                -S::ONE
            };
            let rate = si * sk * self.tmp.at(i);
            if rate < -floor {
                let tau = (si * self.mu.at(i)) / (-rate);
                if best.is_none_or(|(_, t)| tau < t) {
                    best = Some((i, tau));
                }
            }
        }
        let (blocking, tau) = best.ok_or(QpError::Infeasible)?;
        for (mu, &t) in self.mu.iter_mut().zip(self.tmp.iter()).take(k) {
            *mu = mu.mul_add(tau, sk * t);
        }
        self.remove(blocking);
        Ok(())
    }
}

/// `x <- L^-T x` for the unit lower factor `lf` (row stride `c`), by rows
/// of `L` (contiguous): once `x_r` is final, `x_i -= L_ri x_r` for `i < r`.
#[inline]
fn back_substitute<S: QpScalar>(lf: &[S], c: usize, x: &mut [S]) {
    for r in (1..x.len()).rev() {
        // `r < x.len()`; the checked split keeps the panic path out.
        let Some((head, tail)) = x.split_at_mut_checked(r) else {
            continue;
        };
        let xr = tail.at(0);
        let row = lf.get(r * c..r * c + r).unwrap_or(&[]);
        for (xi, &l) in head.iter_mut().zip(row) {
            *xi -= l * xr;
        }
    }
}
