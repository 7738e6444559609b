//! [`Qp16SetSolver`]: the same iterations as [`super::Qp16Solver`] (the
//! same decision rules, the same tables) with the factorisation replaced by
//! a table per active set: `M_A^-1 = ((H^-1)_AA)^-1` and `W_A = P_IA
//! M_A^-1` precomputed offline for every subset `A` of the variables
//! ([`Qp16SetTables`], `N 2^(N-1)` entries per variable: 128 numbers for
//! `N = 4`). An iteration is then `N` rounded MACs of `|A|` terms (`nu* =
//! M_A^-1 r`, `w_I = w_unc_I - W_A r`) and no division: the kernel for small
//! `N`, where the factor updates' fixed costs dominate.
#![allow(clippy::needless_range_loop)] // several arrays indexed together

use super::arith::{frac30, rows_round};
use super::solver::{Qp16Error, Qp16Info, Qp16Start, charge, stamp};
use super::tables::Qp16Tables;

/// The per-active-set tables (`S = 2^N` sets, `E = N^2 2^(N-1)` entries;
/// built by `Qp16Tables::set_tables` with the `std` feature). For the set
/// with bit mask `A` (`k` members in increasing order) at `offset[A]`:
/// `M_A^-1` (`k x k`, row-major, [`Qp16SetTables::minv_bits`] fraction
/// bits), then `W_A` (`(N - k) x k`, the inactive variables in increasing
/// order, [`Qp16SetTables::w_bits`] fraction bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qp16SetTables<const N: usize, const S: usize, const E: usize> {
    /// Start of each set's block in `data`.
    pub offset: [u16; S],
    /// The blocks.
    pub data: [i32; E],
    /// Fraction bits of `M_A^-1` (16 to 30; the multipliers come out in
    /// Q15.16). The solver uses this shift for the whole block.
    pub minv_bits: u8,
    /// Fraction bits of `W_A`: equal to `minv_bits` (one shift per block).
    pub w_bits: u8,
}

/// One variable's state, one record per variable so that the AVR pass
/// routines (`qp16::sets_avr`) walk them with one pointer and fixed
/// offsets (checked at compile time on the AVR). Public as
/// [`super::probe::PassVar`] for the tests that run the pass routines on
/// records of their own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub struct Var {
    /// The unconstrained solution `w_unc` (raw Q15.16), offset 0.
    pub unc: i32,
    /// The lower bound, offset 4.
    pub lo: i32,
    /// The upper bound, offset 8.
    pub hi: i32,
    /// The point, offset 12.
    pub w: i32,
    /// The pass's multiplier of this variable's bound while it is a
    /// member, offset 16.
    pub star: i32,
    /// The entry position plus one, 0 when inactive; offset 20.
    pub pos: u8,
    /// The member's side code: bit 0 upper, bit 1 equal bounds; offset 21.
    pub code: u8,
    /// The current multiplier of its bound, offset 22.
    pub nu: i32,
}

#[cfg(target_arch = "avr")]
const _: () = {
    assert!(core::mem::size_of::<Var>() == super::sets_avr::VAR_SIZE as usize);
    assert!(core::mem::offset_of!(Var, lo) == 4);
    assert!(core::mem::offset_of!(Var, hi) == 8);
    assert!(core::mem::offset_of!(Var, w) == 12);
    assert!(core::mem::offset_of!(Var, star) == 16);
    assert!(core::mem::offset_of!(Var, pos) == 20);
    assert!(core::mem::offset_of!(Var, code) == 21);
    assert!(core::mem::offset_of!(Var, nu) == 22);
};

const VAR0: Var = Var {
    unc: 0,
    lo: 0,
    hi: 0,
    w: 0,
    star: 0,
    pos: 0,
    code: 0,
    nu: 0,
};

/// The solver state of the per-set kernel (about `40 N` bytes).
#[derive(Clone, Debug)]
pub struct Qp16SetSolver<const N: usize> {
    var: [Var; N],
    active: [u8; N],
    count: usize,
    w: [i32; N],
    r: [i32; N],
    out: [i32; N],
}

impl<const N: usize> Default for Qp16SetSolver<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Qp16SetSolver<N> {
    /// An empty solver (`1 <= N <= 8`).
    pub const fn new() -> Self {
        Qp16SetSolver {
            var: [VAR0; N],
            active: [0; N],
            count: 0,
            w: [0; N],
            r: [0; N],
            out: [0; N],
        }
    }

    /// As [`super::Qp16Solver::solution`].
    pub fn solution(&self) -> &[i32; N] {
        &self.w
    }

    /// As [`super::Qp16Solver::active_set`].
    pub fn active_set(&self) -> impl Iterator<Item = (u8, bool)> + '_ {
        (0..self.count.min(N)).map(|p| {
            (
                self.active[p],
                self.var[self.active[p] as usize % N].code & 1 == 1,
            )
        })
    }

    /// Forgets the active set.
    pub fn reset(&mut self) {
        self.count = 0;
        for v in self.var.iter_mut() {
            v.pos = 0;
        }
    }

    /// As [`super::Qp16Solver::fallback`].
    pub fn fallback(&self) -> [i32; N] {
        core::array::from_fn(|i| {
            let v = &self.var[i];
            let (lo, hi) = (v.lo, v.hi);
            if lo > hi {
                ((lo as i64 + hi as i64) >> 1) as i32
            } else {
                v.unc.clamp(lo, hi)
            }
        })
    }

    /// As [`super::Qp16Solver::solve`], with the per-set tables `s` of the
    /// same problem.
    ///
    /// # Errors
    /// [`Qp16Error`]; [`Qp16SetSolver::fallback`] then gives a bounded
    /// input.
    #[inline(never)]
    pub fn solve<const P: usize, const S: usize, const E: usize>(
        &mut self,
        t: &Qp16Tables<N, P>,
        s: &Qp16SetTables<N, S, E>,
        theta: &[i32; P],
        start: Qp16Start,
    ) -> Result<Qp16Info, Qp16Error> {
        let t0 = stamp();
        let unc = t.unconstrained(theta);
        for i in 0..N {
            let v = &mut self.var[i];
            v.unc = unc[i];
            v.lo = t.lb[i].eval(theta);
            v.hi = t.ub[i].eval(theta);
        }
        charge(0, t0);
        for i in 0..N {
            if self.var[i].lo > self.var[i].hi {
                self.w = self.fallback();
                for (v, w) in self.var.iter_mut().zip(self.w) {
                    v.w = w; // the point of the last return, as `w`
                }
                return Err(Qp16Error::InvalidBounds);
            }
        }
        match start {
            Qp16Start::Cold => self.reset(),
            Qp16Start::Warm => self.refactor(),
        }
        for v in self.var.iter_mut() {
            v.nu = 0;
        }
        let mut iterations: u16 = 0;
        let limit = t.dual_tol.saturating_neg();
        loop {
            // One pass: the members' residuals, the block product, the
            // multipliers with the blocking test, then (none blocking) the
            // primal point with the most-violated scan.
            let t0 = stamp();
            let k = self.count.min(N);
            let (mask, q) = members(&self.var, &mut self.r);
            let base = s.offset.get(mask).copied().unwrap_or(0) as usize;
            // The set's whole block (M_A^-1 rows, then W_A rows: N rows of
            // k) times r in one call: the multipliers and W_A r.
            let block = s.data.get(base..base + N * k).unwrap_or(&[]);
            rows_round(block, &self.r[..k.min(q)], s.minv_bits, &mut self.out);
            charge(1, t0);
            let t0 = stamp();
            let blocking = self.star_blocking(limit);
            charge(2, t0);
            match blocking {
                None => {
                    // nu = star (by the scan), the point, the most violated.
                    let t0 = stamp();
                    let most = self.primal_most_violated(k, t.primal_tol);
                    charge(4, t0);
                    match most {
                        None => {
                            self.copy_point();
                            return Ok(Qp16Info {
                                iterations,
                                active: k as u8,
                            });
                        }
                        Some((j, code)) => {
                            if iterations >= t.max_iterations {
                                self.copy_point();
                                return Err(Qp16Error::IterationLimit);
                            }
                            // `j < N` (the scan's); `get_mut` keeps the
                            // panic path out.
                            let (true, Some(v)) = (k < N, self.var.get_mut(j)) else {
                                self.copy_point();
                                return Err(Qp16Error::Infeasible);
                            };
                            self.active[k] = j as u8;
                            v.pos = k as u8 + 1;
                            v.code = code;
                            v.nu = 0;
                            self.count = k + 1;
                        }
                    }
                }
                Some((p, alpha)) => {
                    if iterations >= t.max_iterations {
                        self.copy_point();
                        return Err(Qp16Error::IterationLimit);
                    }
                    let t0 = stamp();
                    // nu += alpha (star - nu): all members' rounded
                    // products in one call (r and out are free again: the
                    // difference and the step).
                    for i in 0..k {
                        let v = &self.var[self.active[i] as usize % N];
                        self.r[i] = v.star.saturating_sub(v.nu);
                    }
                    rows_round(&self.r[..k], &[alpha], 30, &mut self.out[..k]);
                    for i in 0..k {
                        let v = &mut self.var[self.active[i] as usize % N];
                        v.nu = v.nu.saturating_add(self.out[i]);
                    }
                    self.remove(p);
                    charge(6, t0);
                }
            }
            iterations = iterations.saturating_add(1);
        }
    }

    /// The point of the last scan (each record's `w`) as the solution.
    fn copy_point(&mut self) {
        for (w, v) in self.w.iter_mut().zip(&self.var) {
            *w = v.w;
        }
    }

    /// Keeps the stored active set in its order (absent bounds dropped).
    fn refactor(&mut self) {
        let k = self.count.min(N);
        let active = self.active;
        self.reset();
        for p in 0..k {
            let j = active[p] as usize;
            if j >= N || self.var[j].pos != 0 {
                continue;
            }
            let v = &mut self.var[j];
            // The record keeps its side code across `reset`.
            let upper = v.code & 1 == 1;
            let absent = if upper {
                v.hi == i32::MAX
            } else {
                v.lo == i32::MIN
            };
            if absent {
                continue;
            }
            let c = self.count;
            let code = u8::from(upper) | if v.lo == v.hi { 2 } else { 0 };
            self.active[c] = j as u8;
            v.pos = c as u8 + 1;
            v.code = code;
            self.count = c + 1;
        }
    }

    fn remove(&mut self, p: usize) {
        let k = self.count.min(N);
        // `p` is an active position (the blocking test's).
        if p >= k {
            return;
        }
        self.var[self.active[p] as usize % N].pos = 0;
        for r in p..k - 1 {
            self.active[r] = self.active[r + 1];
            self.var[self.active[r] as usize % N].pos = r as u8 + 1;
        }
        self.count = k - 1;
    }

    /// The multipliers (each member's `star`, from the pass's block
    /// `out`) and the blocking test: the strictly smallest step over the
    /// wrong-sign ones (lowest position on ties).
    #[inline(always)]
    fn star_blocking(&mut self, limit: i32) -> Option<(usize, i32)> {
        let cand = stars(&mut self.var, &self.out, limit);
        if cand == 0 {
            return None;
        }
        let mut blocking: Option<(usize, i32)> = None;
        for j in 0..N {
            if (cand >> j) & 1 == 0 {
                continue;
            }
            let v = &self.var[j];
            let p = (v.pos as usize).wrapping_sub(1) % N;
            let (star, cur) = if v.code == 1 {
                (v.star, v.nu)
            } else {
                (v.star.saturating_neg(), v.nu.saturating_neg())
            };
            let alpha = frac30(cur, star);
            if blocking.is_none_or(|(bp, a)| alpha < a || (alpha == a && p < bp)) {
                blocking = Some((p, alpha));
            }
        }
        blocking
    }

    /// The members' multipliers `nu = star`, the point `w` (`w_I = w_unc_I -
    /// W_A r` from the pass's block `out`, active variables exactly on
    /// their bound, into each variable's record) and the most violated
    /// inactive bound.
    #[inline(always)]
    fn primal_most_violated(&mut self, k: usize, tol: i32) -> Option<(usize, u8)> {
        if tol < 0 {
            return self.primal_most_violated_any(k, tol);
        }
        // tol >= 0 (every built table), and lo <= hi: at most one side is
        // violated, so only a bound the point lies beyond is a candidate
        // (the same choice as the general rule below).
        let (best, code) = scan(&mut self.var, &self.out, k, tol);
        (best < N).then_some((best, code))
    }

    /// [`Self::primal_most_violated`] for any tolerance.
    #[inline(never)]
    fn primal_most_violated_any(&mut self, k: usize, tol: i32) -> Option<(usize, u8)> {
        let (mut best, mut code, mut worst) = (N, 0u8, tol);
        let mut q = k;
        for j in 0..N {
            let x = &mut self.var[j];
            let (lo, hi) = (x.lo, x.hi);
            if x.pos != 0 {
                x.w = if x.code & 1 == 1 { hi } else { lo };
                x.nu = x.star;
                continue;
            }
            let v = x.unc.saturating_sub(self.out[q % N]);
            q += 1;
            x.w = v;
            let (up, down) = (v.saturating_sub(hi), lo.saturating_sub(v));
            let (viol, side) = if up > down { (up, 1) } else { (down, 0) };
            if viol > worst {
                worst = viol;
                best = j;
                code = side | if lo == hi { 2 } else { 0 };
            }
        }
        (best < N).then_some((best, code))
    }
}

/// The members' residuals `r = w_unc_A - b_A` in increasing variable
/// order; the set's bit mask and the member count. On the AVR one
/// assembly routine (`sets_avr::members_avr`).
#[inline(always)]
pub(super) fn members<const N: usize>(var: &[Var; N], r: &mut [i32; N]) -> (usize, usize) {
    #[cfg(target_arch = "avr")]
    if N <= 8 {
        // SAFETY: N (1..=8) records of the checked layout; at most N
        // members, so at most N residuals written to `r`.
        let (mask, q) = unsafe {
            super::sets_avr::members_avr(var.as_ptr() as *const u8, N as u8, r.as_mut_ptr())
        };
        return (mask as usize, q as usize);
    }
    let (mut mask, mut q) = (0usize, 0usize);
    for (j, v) in var.iter().enumerate() {
        if v.pos != 0 {
            mask |= 1 << j;
            let b = if v.code & 1 == 1 { v.hi } else { v.lo };
            r[q % N] = v.unc.saturating_sub(b);
            q += 1;
        }
    }
    (mask, q)
}

/// Each member's multiplier `star` (the block's row of its rank) into its
/// record; the bit mask (by variable) of the members whose multiplier,
/// signed for its side, is below `limit` (equal-bound members never). On
/// the AVR one assembly routine (`sets_avr::stars_avr`).
#[inline(always)]
pub(super) fn stars<const N: usize>(var: &mut [Var; N], out: &[i32; N], limit: i32) -> u32 {
    #[cfg(target_arch = "avr")]
    if N <= 8 {
        // SAFETY: N (1..=8) records of the checked layout; at most N
        // members, so at most N values read from `out`.
        return u32::from(unsafe {
            super::sets_avr::stars_avr(var.as_mut_ptr() as *mut u8, N as u8, out.as_ptr(), limit)
        });
    }
    let (mut cand, mut q) = (0u32, 0usize);
    for (j, v) in var.iter_mut().enumerate() {
        if v.pos == 0 {
            continue;
        }
        let star = out[q % N];
        q += 1;
        v.star = star;
        if v.code >= 2 {
            continue;
        }
        let s = if v.code == 1 {
            star
        } else {
            star.saturating_neg()
        };
        if s < limit {
            cand |= 1 << (j % 32);
        }
    }
    cand
}

/// The point and the most violated bound for a tolerance `tol >= 0`:
/// each member's `nu = star`, each variable's `w` (members exactly on
/// their bound, the others `w_unc - out[q]` from `out[k]` on) and `(best,
/// code)`, `best = N` if no bound is violated beyond `tol`. On the AVR one
/// assembly routine (`sets_avr::scan_avr`).
#[inline(always)]
pub(super) fn scan<const N: usize>(
    var: &mut [Var; N],
    out: &[i32; N],
    k: usize,
    tol: i32,
) -> (usize, u8) {
    #[cfg(target_arch = "avr")]
    if N <= 8 && k <= N {
        // SAFETY: N (1..=8) records of the checked layout; the N - k
        // inactive variables read out[k..N].
        let (best, code) = unsafe {
            super::sets_avr::scan_avr(
                var.as_mut_ptr() as *mut u8,
                N as u8,
                out.as_ptr().add(k),
                tol,
            )
        };
        return ((best as usize).min(N), code);
    }
    let (mut best, mut code, mut worst) = (N, 0u8, tol);
    let mut q = k;
    for (j, x) in var.iter_mut().enumerate() {
        let (lo, hi) = (x.lo, x.hi);
        if x.pos != 0 {
            x.w = if x.code & 1 == 1 { hi } else { lo };
            x.nu = x.star;
            continue;
        }
        let v = x.unc.saturating_sub(out[q % N]);
        q += 1;
        x.w = v;
        let (viol, side) = if v > hi {
            (v.saturating_sub(hi), 1)
        } else if v < lo {
            (lo.saturating_sub(v), 0)
        } else {
            continue;
        };
        if viol > worst {
            worst = viol;
            best = j;
            code = side | if lo == hi { 2 } else { 0 };
        }
    }
    (best, code)
}
