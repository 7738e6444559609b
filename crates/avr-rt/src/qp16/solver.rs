//! The iterations: kestrel-qp's decision rules (most violated bound,
//! blocking dual step, LDL' of `M = P_AA` updated on add and remove) on
//! the fixed-point tables.
#![allow(clippy::needless_range_loop)] // factor rows and columns indexed together

use super::arith::{Recip, frac30, mac_round, mul_round};
use super::tables::Qp16Tables;

/// Cycles spent per phase of the solves since start-up (feature
/// `qp16-profile`, AVR only; Timer1 must run at the CPU clock): rows,
/// `star` solve, blocking test, primal point, most violated, add, remove.
#[cfg(all(target_arch = "avr", feature = "qp16-profile"))]
pub static mut QP16_PROFILE: [u32; 7] = [0; 7];

/// Timer1's count (profiling only; 0 without the feature).
#[inline(always)]
pub(super) fn stamp() -> u16 {
    #[cfg(all(target_arch = "avr", feature = "qp16-profile"))]
    // SAFETY: reads TCNT1 (low byte first latches the high byte).
    unsafe {
        let lo = core::ptr::read_volatile(0x84 as *const u8);
        let hi = core::ptr::read_volatile(0x85 as *const u8);
        return u16::from_le_bytes([lo, hi]);
    }
    #[allow(unreachable_code)]
    0
}

/// Adds the cycles since `_since` to a phase (profiling only).
#[inline(always)]
pub(super) fn charge(_phase: usize, _since: u16) {
    #[cfg(all(target_arch = "avr", feature = "qp16-profile"))]
    // SAFETY: single-threaded profiling counters.
    unsafe {
        let p = &mut *core::ptr::addr_of_mut!(QP16_PROFILE);
        if let Some(v) = p.get_mut(_phase) {
            *v = v.wrapping_add(u32::from(stamp().wrapping_sub(_since)));
        }
    }
}

/// How a solve starts (as `kestrel_qp::Start`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Qp16Start {
    /// From the empty active set.
    Cold,
    /// From the previous solve's final active set, re-added in its order
    /// with zero multipliers.
    Warm,
}

/// Why a solve failed; the caller then applies [`Qp16Solver::fallback`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Qp16Error {
    /// A lower bound exceeds its upper bound at this theta.
    InvalidBounds,
    /// A pivot of the active set's factor vanished (an entering bound
    /// numerically dependent on the active ones; not reached by a table
    /// the builder accepted) or more than `N` bounds became active.
    Infeasible,
    /// [`Qp16Tables::max_iterations`] active-set changes were made without
    /// reaching the optimum.
    IterationLimit,
}

impl core::fmt::Display for Qp16Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Qp16Error::InvalidBounds => "a lower bound exceeds its upper bound",
            Qp16Error::Infeasible => "singular active set",
            Qp16Error::IterationLimit => "iteration limit reached",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Qp16Error {}

/// What a successful solve did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qp16Info {
    /// Active-set changes (adds plus removals), counted as kestrel-qp.
    pub iterations: u16,
    /// Size of the final active set.
    pub active: u8,
}

/// The solver's state for `N` variables: the active set, its LDL' factor,
/// the multipliers and the last point (all Q15.16 raw, about `8 N^2 + 40 N`
/// bytes). `Copy`-free, no allocation; one per controller.
#[derive(Clone, Debug)]
pub struct Qp16Solver<const N: usize> {
    /// Unit lower factor `L` (row `i`, columns `< i`).
    l: [[i32; N]; N],
    d: [i32; N],
    rd: [Recip; N],
    nu: [i32; N],
    star: [i32; N],
    /// `D^-1 L^-1 (w_unc_A - b_A)`, valid for the first `valid` positions
    /// (an add leaves the earlier ones, a removal at `p` the first `p`).
    y: [i32; N],
    /// `L^-1 (w_unc_A - b_A)` (Q15.16), valid as `y`.
    fwd: [i32; N],
    valid: usize,
    /// Variable of each active position; bit 0 of `side` the upper bound,
    /// bit 1 an equality (`lb = ub`: never blocks).
    active: [u8; N],
    side: [u8; N],
    /// Position + 1 of each variable in the active list (0: inactive).
    pos: [u8; N],
    count: usize,
    w: [i32; N],
    unc: [i32; N],
    lo: [i32; N],
    hi: [i32; N],
}

impl<const N: usize> Default for Qp16Solver<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Qp16Solver<N> {
    /// An empty solver (`N <= 255`).
    pub const fn new() -> Self {
        Qp16Solver {
            l: [[0; N]; N],
            d: [0; N],
            rd: [Recip { q: 0, b: 0 }; N],
            nu: [0; N],
            star: [0; N],
            y: [0; N],
            fwd: [0; N],
            valid: 0,
            active: [0; N],
            side: [0; N],
            pos: [0; N],
            count: 0,
            w: [0; N],
            unc: [0; N],
            lo: [0; N],
            hi: [0; N],
        }
    }

    /// The last solution in the scaled variables (raw Q15.16 of `w = z /
    /// 2^s`; convert with [`Qp16Tables::to_problem_f32`]). Active
    /// variables sit exactly on their bound.
    pub fn solution(&self) -> &[i32; N] {
        &self.w
    }

    /// The active set of the last solve: `(variable, upper)` in the order
    /// of entry.
    pub fn active_set(&self) -> impl Iterator<Item = (u8, bool)> + '_ {
        (0..self.count.min(N)).map(|p| (self.active[p], self.side[p] & 1 == 1))
    }

    /// Forgets the active set (the next warm start is a cold one).
    pub fn reset(&mut self) {
        self.clear();
    }

    /// The safe input after a failed solve at the same theta: the
    /// unconstrained solution clamped to the bounds (to the midpoint of an
    /// empty box), in the scaled variables. Always within the bounds when
    /// they are consistent.
    pub fn fallback(&self) -> [i32; N] {
        core::array::from_fn(|i| {
            let (lo, hi) = (self.lo[i], self.hi[i]);
            if lo > hi {
                ((lo as i64 + hi as i64) >> 1) as i32
            } else {
                self.unc[i].clamp(lo, hi)
            }
        })
    }

    /// Test only: `max |L D L' - P_AA|` over `max |P_AA|`.
    #[cfg(test)]
    pub(super) fn factor_residual<const P: usize>(&self, t: &Qp16Tables<N, P>) -> f64 {
        let k = self.count;
        let lv = |r: usize, c: usize| -> f64 {
            if r == c {
                1.0
            } else if c < r {
                self.l[r][c] as f64 / 2f64.powi(t.l_bits as i32)
            } else {
                0.0
            }
        };
        let (mut worst, mut big) = (0.0f64, 0.0f64);
        for r in 0..k {
            for c in 0..k {
                let m: f64 = (0..k).map(|i| lv(r, i) * lv(c, i) * self.d[i] as f64).sum();
                let p = t.hinv[self.active[r] as usize][self.active[c] as usize] as f64;
                worst = worst.max((m - p).abs());
                big = big.max(p.abs());
            }
        }
        worst / big.max(1.0)
    }

    fn clear(&mut self) {
        self.count = 0;
        self.valid = 0;
        self.pos = [0; N];
    }

    /// Solves at `theta` (Q15.16 raw) with the tables `t`; the solution is
    /// then [`Qp16Solver::solution`].
    ///
    /// # Errors
    /// [`Qp16Error`]; [`Qp16Solver::fallback`] then gives a bounded input.
    #[inline(never)]
    pub fn solve<const P: usize>(
        &mut self,
        t: &Qp16Tables<N, P>,
        theta: &[i32; P],
        start: Qp16Start,
    ) -> Result<Qp16Info, Qp16Error> {
        let t0 = stamp();
        self.unc = t.unconstrained(theta);
        for i in 0..N {
            self.lo[i] = t.lb[i].eval(theta);
            self.hi[i] = t.ub[i].eval(theta);
        }
        charge(0, t0);
        if (0..N).any(|i| self.lo[i] > self.hi[i]) {
            self.w = self.fallback();
            return Err(Qp16Error::InvalidBounds);
        }
        match start {
            Qp16Start::Cold => self.clear(),
            Qp16Start::Warm => self.refactor(t)?,
        }
        self.nu = [0; N];
        let mut iterations: u16 = 0;
        loop {
            let t0 = stamp();
            self.solve_star(t);
            charge(1, t0);
            let t0 = stamp();
            let blocking = self.blocking(t.dual_tol);
            charge(2, t0);
            match blocking {
                None => {
                    let k = self.count.min(N);
                    self.nu[..k].copy_from_slice(&self.star[..k]);
                    let t0 = stamp();
                    self.primal(t);
                    charge(3, t0);
                    let t0 = stamp();
                    let most = self.most_violated(t.primal_tol);
                    charge(4, t0);
                    match most {
                        None => {
                            return Ok(Qp16Info {
                                iterations,
                                active: k as u8,
                            });
                        }
                        Some((j, side)) => {
                            if iterations >= t.max_iterations {
                                return Err(Qp16Error::IterationLimit);
                            }
                            if self.count >= N {
                                return Err(Qp16Error::Infeasible);
                            }
                            let t0 = stamp();
                            self.add(t, j, side)?;
                            charge(5, t0);
                        }
                    }
                }
                Some((p, alpha)) => {
                    if iterations >= t.max_iterations {
                        return Err(Qp16Error::IterationLimit);
                    }
                    for i in 0..self.count.min(N) {
                        let diff = self.star[i].saturating_sub(self.nu[i]);
                        self.nu[i] = self.nu[i].saturating_add(mul_round(alpha, diff, 30));
                    }
                    let t0 = stamp();
                    self.remove(t, p)?;
                    charge(6, t0);
                }
            }
            iterations = iterations.saturating_add(1);
        }
    }

    /// Re-adds the stored active set in its order (absent bounds dropped).
    #[inline(never)]
    fn refactor<const P: usize>(&mut self, t: &Qp16Tables<N, P>) -> Result<(), Qp16Error> {
        let k = self.count.min(N);
        let (active, side) = (self.active, self.side);
        self.clear();
        self.valid = 0;
        for p in 0..k {
            let j = active[p] as usize;
            if j >= N || self.pos[j] != 0 {
                continue;
            }
            let upper = side[p] & 1 == 1;
            let absent = if upper {
                self.hi[j] == i32::MAX
            } else {
                self.lo[j] == i32::MIN
            };
            if absent {
                continue;
            }
            let code = (side[p] & 1) | if self.lo[j] == self.hi[j] { 2 } else { 0 };
            self.add(t, j, code)?;
        }
        Ok(())
    }

    /// The active bound of position `p`.
    fn bound(&self, p: usize) -> i32 {
        // Positions and variables are below N by construction; `get` keeps
        // the panic path out of the firmware (0 is never reached).
        let (Some(&j), Some(&side)) = (self.active.get(p), self.side.get(p)) else {
            return 0;
        };
        let bounds = if side & 1 == 1 { &self.hi } else { &self.lo };
        bounds.get(j as usize).copied().unwrap_or(0)
    }

    /// `star = M^-1 (w_unc_A - b_A)` through the factor: `L y = r`
    /// (Q15.16) and `D^-1 y` (multiplier format) for the positions not yet
    /// solved (the rows of `L` before them have not changed), then
    /// `L' star = D^-1 y`.
    #[inline(never)]
    fn solve_star<const P: usize>(&mut self, t: &Qp16Tables<N, P>) {
        let k = self.count.min(N);
        let lb = t.l_bits;
        let kd = t.nu_bits.saturating_add(t.p_bits).saturating_sub(16);
        for i in self.valid.min(k)..k {
            let unc = self.unc.get(self.active[i] as usize).copied().unwrap_or(0);
            let r = unc.saturating_sub(self.bound(i));
            let v = mac_round(&self.l[i][..i], &self.fwd[..i], lb);
            self.fwd[i] = r.saturating_sub(v);
            self.y[i] = self.rd[i].div(self.fwd[i], kd);
        }
        self.valid = k;
        self.star[..k].copy_from_slice(&self.y[..k]);
        let mut col = [0i32; N];
        for i in (0..k.saturating_sub(1)).rev() {
            for r in i + 1..k {
                col[r] = self.l[r][i];
            }
            let v = mac_round(&col[i + 1..k], &self.star[i + 1..k], lb);
            self.star[i] = self.star[i].saturating_sub(v);
        }
    }

    /// The blocking position and the step (Q2.30), if any multiplier of
    /// `star` has the wrong sign beyond `tol`: the strictly smallest step
    /// wins (lowest position on ties).
    #[inline(never)]
    fn blocking(&self, tol: i32) -> Option<(usize, i32)> {
        let mut best: Option<(usize, i32)> = None;
        let limit = tol.saturating_neg();
        for p in 0..self.count.min(N) {
            let code = self.side[p];
            if code >= 2 {
                continue;
            }
            let (star, cur) = if code == 1 {
                (self.star[p], self.nu[p])
            } else {
                (self.star[p].saturating_neg(), self.nu[p].saturating_neg())
            };
            if star < limit {
                let alpha = frac30(cur, star);
                if best.is_none_or(|(_, a)| alpha < a) {
                    best = Some((p, alpha));
                }
            }
        }
        best
    }

    /// `w = w_unc - P_{:,A} nu`; active variables exactly on their bound.
    #[inline(never)]
    fn primal<const P: usize>(&mut self, t: &Qp16Tables<N, P>) {
        let k = self.count.min(N);
        let mut row = [0i32; N];
        for i in 0..N {
            if self.pos[i] != 0 {
                self.w[i] = self.bound(self.pos[i] as usize - 1);
                continue;
            }
            for p in 0..k {
                row[p] = t.hinv[i].get(self.active[p] as usize).copied().unwrap_or(0);
            }
            let v = mac_round(
                &row[..k],
                &self.nu[..k],
                t.p_bits.saturating_add(t.nu_bits).saturating_sub(16),
            );
            self.w[i] = self.unc[i].saturating_sub(v);
        }
    }

    /// The inactive bound violated most beyond `tol`: `(variable, side)`,
    /// lowest index on ties.
    #[inline(never)]
    fn most_violated(&self, tol: i32) -> Option<(usize, u8)> {
        let mut best: Option<(usize, u8, i32)> = None;
        for j in 0..N {
            if self.pos[j] != 0 {
                continue;
            }
            let v = self.w[j];
            let (up, down) = (v.saturating_sub(self.hi[j]), self.lo[j].saturating_sub(v));
            let (viol, side) = if up > down { (up, 1) } else { (down, 0) };
            let side = side | if self.lo[j] == self.hi[j] { 2 } else { 0 };
            if viol > tol && best.is_none_or(|(_, _, b)| viol > b) {
                best = Some((j, side, viol));
            }
        }
        best.map(|(j, s, _)| (j, s))
    }

    /// Appends the bound on variable `j` (side code) and its row of the
    /// factor: `t = L^-1 P_{A,j}`, `l = D^-1 t`, `d = P_jj - l't`.
    #[inline(never)]
    fn add<const P: usize>(
        &mut self,
        t: &Qp16Tables<N, P>,
        j: usize,
        code: u8,
    ) -> Result<(), Qp16Error> {
        let k = self.count;
        // A full set or a variable out of range cannot enter (the callers
        // never ask; the checks keep the panic path out).
        if k >= N || j >= N {
            return Err(Qp16Error::Infeasible);
        }
        let mut tv = [0i32; N];
        for i in 0..k {
            let m = t.hinv.get(self.active[i] as usize).map_or(0, |row| row[j]);
            let v = mac_round(&self.l[i][..i], &tv[..i], t.l_bits);
            tv[i] = m.saturating_sub(v);
        }
        let mut lrow = [0i32; N];
        for i in 0..k {
            lrow[i] = self.rd[i].div(tv[i], t.l_bits);
        }
        let diag = t.hinv[j][j];
        let d = diag.saturating_sub(mac_round(&lrow[..k], &tv[..k], t.l_bits));
        // Pivot test (kestrel-qp's d > pivot_tol * diag, here 2^-20).
        let rd = match Recip::new(d, t.pivot_bits) {
            Some(r) if d > diag >> 20 => r,
            _ => return Err(Qp16Error::Infeasible),
        };
        self.l[k] = lrow;
        self.d[k] = d;
        self.rd[k] = rd;
        self.active[k] = j as u8;
        self.side[k] = code;
        self.pos[j] = k as u8 + 1;
        self.nu[k] = 0;
        self.count = k + 1;
        Ok(())
    }

    /// Removes position `p`: deletes its row and column and restores the
    /// trailing block by the rank-one update `+ d_p l_p l_p'` (Gill, Golub,
    /// Murray, Saunders C1), as kestrel-qp.
    #[inline(never)]
    fn remove<const P: usize>(&mut self, t: &Qp16Tables<N, P>, p: usize) -> Result<(), Qp16Error> {
        let lb = t.l_bits;
        let k = self.count.min(N);
        // `p` is an active position (the blocking test's); the check keeps
        // the panic path out.
        if p >= k {
            return Err(Qp16Error::Infeasible);
        }
        let mut alpha = self.d[p];
        let mut wv = [0i32; N];
        for r in p + 1..k {
            wv[r] = self.l[r][p];
        }
        if let Some(pos) = self.pos.get_mut(self.active[p] as usize) {
            *pos = 0;
        }
        self.valid = self.valid.min(p);
        for r in p..k - 1 {
            for col in 0..p {
                self.l[r][col] = self.l[r + 1][col];
            }
            for col in p..r {
                self.l[r][col] = self.l[r + 1][col + 1];
            }
            self.d[r] = self.d[r + 1];
            self.rd[r] = self.rd[r + 1];
            self.nu[r] = self.nu[r + 1];
            self.active[r] = self.active[r + 1];
            self.side[r] = self.side[r + 1];
            if let Some(pos) = self.pos.get_mut(self.active[r] as usize) {
                *pos = r as u8 + 1;
            }
            wv[r] = wv[r + 1];
        }
        self.count = k - 1;
        for i in p..k - 1 {
            let pv = wv[i];
            // dnew = d + alpha pv^2, r = alpha / dnew (<= cond P),
            // beta = pv r, alpha <- d r: no product beyond its own format.
            let pv2 = mul_round(pv, pv, lb);
            let dnew = self.d[i].saturating_add(mul_round(alpha, pv2, lb));
            let rd = Recip::new(dnew, t.pivot_bits).ok_or(Qp16Error::Infeasible)?;
            let r = rd.div(alpha, lb);
            let beta = mul_round(pv, r, lb);
            alpha = mul_round(self.d[i], r, lb);
            self.d[i] = dnew;
            self.rd[i] = rd;
            for r in i + 1..k - 1 {
                let l = self.l[r][i];
                wv[r] = wv[r].saturating_sub(mul_round(pv, l, lb));
                self.l[r][i] = l.saturating_add(mul_round(beta, wv[r], lb));
            }
        }
        Ok(())
    }
}
