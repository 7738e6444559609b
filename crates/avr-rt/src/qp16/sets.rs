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

/// The solver state of the per-set kernel (about `30 N` bytes).
#[derive(Clone, Debug)]
pub struct Qp16SetSolver<const N: usize> {
    nu: [i32; N],
    star: [i32; N],
    active: [u8; N],
    side: [u8; N],
    pos: [u8; N],
    count: usize,
    w: [i32; N],
    unc: [i32; N],
    lo: [i32; N],
    hi: [i32; N],
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
            nu: [0; N],
            star: [0; N],
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

    /// As [`super::Qp16Solver::solution`].
    pub fn solution(&self) -> &[i32; N] {
        &self.w
    }

    /// As [`super::Qp16Solver::active_set`].
    pub fn active_set(&self) -> impl Iterator<Item = (u8, bool)> + '_ {
        (0..self.count.min(N)).map(|p| (self.active[p], self.side[p] & 1 == 1))
    }

    /// Forgets the active set.
    pub fn reset(&mut self) {
        self.count = 0;
        self.pos = [0; N];
    }

    /// As [`super::Qp16Solver::fallback`].
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
        self.unc = t.unconstrained(theta);
        for i in 0..N {
            self.lo[i] = t.lb[i].eval(theta);
            self.hi[i] = t.ub[i].eval(theta);
        }
        charge(0, t0);
        for i in 0..N {
            if self.lo[i] > self.hi[i] {
                self.w = self.fallback();
                return Err(Qp16Error::InvalidBounds);
            }
        }
        match start {
            Qp16Start::Cold => self.reset(),
            Qp16Start::Warm => self.refactor(),
        }
        self.nu = [0; N];
        let mut iterations: u16 = 0;
        let limit = t.dual_tol.saturating_neg();
        loop {
            // One pass: the members' residuals, the block product, the
            // multipliers with the blocking test, then (none blocking) the
            // primal point with the most-violated scan, each in one loop.
            let t0 = stamp();
            let k = self.count.min(N);
            let mut r = [0i32; N];
            let mut rank = [0u8; N];
            let (mask, q) = self.members(&mut r, &mut rank);
            let base = s.offset.get(mask).copied().unwrap_or(0) as usize;
            // The set's whole block (M_A^-1 rows, then W_A rows: N rows of
            // k) times r in one call: the multipliers and W_A r.
            let mut out = [0i32; N];
            let block = s.data.get(base..base + N * k).unwrap_or(&[]);
            rows_round(block, &r[..k.min(q)], s.minv_bits, &mut out);
            charge(1, t0);
            let t0 = stamp();
            let blocking = self.star_blocking(&out, &rank, limit);
            charge(2, t0);
            match blocking {
                None => {
                    self.nu[..k].copy_from_slice(&self.star[..k]);
                    let t0 = stamp();
                    let most = self.primal_most_violated(&out, t.primal_tol);
                    charge(4, t0);
                    match most {
                        None => {
                            return Ok(Qp16Info {
                                iterations,
                                active: k as u8,
                            });
                        }
                        Some((j, code)) => {
                            if iterations >= t.max_iterations {
                                return Err(Qp16Error::IterationLimit);
                            }
                            if k >= N {
                                return Err(Qp16Error::Infeasible);
                            }
                            self.active[k] = j as u8;
                            self.side[k] = code;
                            self.pos[j] = k as u8 + 1;
                            self.nu[k] = 0;
                            self.count = k + 1;
                        }
                    }
                }
                Some((p, alpha)) => {
                    if iterations >= t.max_iterations {
                        return Err(Qp16Error::IterationLimit);
                    }
                    let t0 = stamp();
                    // nu += alpha (star - nu): all members' rounded
                    // products in one call.
                    // (r and out are free again: the difference and the step.)
                    for i in 0..k {
                        r[i] = self.star[i].saturating_sub(self.nu[i]);
                    }
                    rows_round(&r[..k], &[alpha], 30, &mut out[..k]);
                    for i in 0..k {
                        self.nu[i] = self.nu[i].saturating_add(out[i]);
                    }
                    self.remove(p);
                    charge(6, t0);
                }
            }
            iterations = iterations.saturating_add(1);
        }
    }

    /// Keeps the stored active set in its order (absent bounds dropped).
    fn refactor(&mut self) {
        let k = self.count.min(N);
        let (active, side) = (self.active, self.side);
        self.reset();
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
            let c = self.count;
            self.active[c] = j as u8;
            self.side[c] = (side[p] & 1) | if self.lo[j] == self.hi[j] { 2 } else { 0 };
            self.pos[j] = c as u8 + 1;
            self.count = c + 1;
        }
    }

    fn remove(&mut self, p: usize) {
        let k = self.count;
        self.pos[self.active[p] as usize] = 0;
        for r in p..k - 1 {
            self.nu[r] = self.nu[r + 1];
            self.active[r] = self.active[r + 1];
            self.side[r] = self.side[r + 1];
            self.pos[self.active[r] as usize] = r as u8 + 1;
        }
        self.count = k - 1;
    }

    /// The point `w` (`w_I = w_unc_I - W_A r` from the pass's block
    /// `out`, active variables exactly on their bound) and, in the same
    /// loop, the most violated inactive bound.
    /// The members' residuals `r = w_unc_A - b_A` in increasing variable
    /// order, `rank[p]` the rank of the member at entry position `p`;
    /// returns the set's bit mask and the member count.
    #[inline(always)]
    fn members(&self, r: &mut [i32; N], rank: &mut [u8; N]) -> (usize, usize) {
        let mut mask = 0usize;
        let mut q = 0usize;
        for j in 0..N {
            let p = self.pos[j] as usize;
            if p != 0 && p <= N {
                mask |= 1 << j;
                rank[p - 1] = q as u8;
                let b = if self.side[p - 1] & 1 == 1 {
                    self.hi[j]
                } else {
                    self.lo[j]
                };
                r[q % N] = self.unc[j].saturating_sub(b);
                q += 1;
            }
        }
        (mask, q)
    }

    /// The multipliers `star` (entry order) from the pass's block `out`
    /// and the blocking test: the strictly smallest step over the
    /// wrong-sign ones (lowest position on ties).
    #[inline(always)]
    fn star_blocking(
        &mut self,
        out: &[i32; N],
        rank: &[u8; N],
        limit: i32,
    ) -> Option<(usize, i32)> {
        let mut blocking: Option<(usize, i32)> = None;
        for p in 0..self.count.min(N) {
            let star = out[rank[p] as usize % N];
            self.star[p] = star;
            let code = self.side[p];
            if code >= 2 {
                continue;
            }
            let (star, cur) = if code == 1 {
                (star, self.nu[p])
            } else {
                (star.saturating_neg(), self.nu[p].saturating_neg())
            };
            if star < limit {
                let alpha = frac30(cur, star);
                if blocking.is_none_or(|(_, a)| alpha < a) {
                    blocking = Some((p, alpha));
                }
            }
        }
        blocking
    }

    #[inline(always)]
    fn primal_most_violated(&mut self, out: &[i32; N], tol: i32) -> Option<(usize, u8)> {
        if tol < 0 {
            return self.primal_most_violated_any(out, tol);
        }
        // tol >= 0 (every built table), and lo <= hi: at most one side is
        // violated, so only a bound the point lies beyond is a candidate
        // (the same choice as the general rule below).
        let (mut best, mut code, mut worst) = (N, 0u8, tol);
        let mut q = self.count;
        for j in 0..N {
            let p = self.pos[j] as usize;
            let (lo, hi) = (self.lo[j], self.hi[j]);
            if p != 0 {
                self.w[j] = if self.side[(p - 1) % N] & 1 == 1 {
                    hi
                } else {
                    lo
                };
                continue;
            }
            let v = self.unc[j].saturating_sub(out[q % N]);
            q += 1;
            self.w[j] = v;
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
        (best < N).then_some((best, code))
    }

    /// [`Self::primal_most_violated`] for any tolerance.
    #[inline(never)]
    fn primal_most_violated_any(&mut self, out: &[i32; N], tol: i32) -> Option<(usize, u8)> {
        let (mut best, mut code, mut worst) = (N, 0u8, tol);
        let mut q = self.count;
        for j in 0..N {
            let p = self.pos[j] as usize;
            let (lo, hi) = (self.lo[j], self.hi[j]);
            if p != 0 {
                self.w[j] = if self.side[(p - 1) % N] & 1 == 1 {
                    hi
                } else {
                    lo
                };
                continue;
            }
            let v = self.unc[j].saturating_sub(out[q % N]);
            q += 1;
            self.w[j] = v;
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
