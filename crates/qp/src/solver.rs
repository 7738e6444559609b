//! The dual active-set solver: set-up (LDL' of `H`, `H^-1`, `H^-1 g_j`) and
//! the accessors; the Goldfarb-Idnani iterations with LDL' updates of the
//! active constraints' `M = G_A H^-1 G_A'` are in the `iterate` module.
//!
//! Coordinates: the iterations work on `z` itself. With signed multipliers
//! `mu` (positive at an upper bound, negative at a lower one),
//! `z = z_unc - H^-1 G_A' mu` (`z_unc = -H^-1 q`) and
//! `M mu = G_A z_unc - b_A`. The set-up keeps `H^-1` and `w_j = H^-1 g_j`
//! for each row of `G`, so that every entry of `M` a simple bound takes part
//! in is an entry of `H^-1` or of a `w_j` (`O(1)`), a row against a row a
//! dot product `g_i' w_j`, and a bound's value at `z` is `z_i` itself.

use crate::{QpError, QpSettings};
use core::ops::Div;
use kestrel_core::Scalar;

/// The arithmetic the solver needs: [`Scalar`] with a division (`f32`,
/// `f64`).
pub trait QpScalar: Scalar + Div<Output = Self> {}
impl<S: Scalar + Div<Output = S>> QpScalar for S {}

/// Which bound of a constraint is active.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The lower bound (`l` or `lb`); its multiplier is `<= 0`.
    Lower,
    /// The upper bound (`u` or `ub`); its multiplier is `>= 0`.
    Upper,
}

/// One active constraint: index `j < m` is row `j` of `G`, index `m + i`
/// the simple bound on `z_i`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ActiveConstraint {
    /// The constraint's index (rows of `G` first, then the bounds).
    pub index: usize,
    /// Which of its bounds is active.
    pub side: Side,
}

/// How a solve starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// From the empty active set (the unconstrained optimum).
    Cold,
    /// From the solver's current active set: the previous solve's final
    /// set, or the one given to [`QpSolver::set_active_set`]. Its
    /// factorisation is rebuilt; constraints that have become linearly
    /// dependent or whose bound is now infinite are dropped.
    Warm,
}

/// The per-solve data: the linear term and the bounds (each may be
/// infinite; none NaN). `l`, `u` have `m` entries, `q`, `lb`, `ub` `n`.
#[derive(Debug, Clone, Copy)]
pub struct QpData<'a, S> {
    /// Linear term `q`, `n` entries, finite.
    pub q: &'a [S],
    /// Lower bounds of `G z`, `m` entries.
    pub l: &'a [S],
    /// Upper bounds of `G z`, `m` entries.
    pub u: &'a [S],
    /// Lower bounds of `z`, `n` entries.
    pub lb: &'a [S],
    /// Upper bounds of `z`, `n` entries.
    pub ub: &'a [S],
}

/// What a successful solve did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SolveInfo {
    /// Active-set changes made (constraints added plus removed).
    pub iterations: usize,
    /// Size of the final active set ([`QpSolver::active_set`]).
    pub active: usize,
}

/// Length of the scalar workspace for `n` variables and `m` rows of `G`:
/// `n^2 + 2 m n + 3 n + 7 (n + 1) + (n + 1)^2` (saturating at `usize::MAX`,
/// which no slice reaches: sizes too large for the address space, as on a
/// 16-bit AVR, are refused by [`QpSolver::new`] instead of wrapping).
pub const fn scalar_len(n: usize, m: usize) -> usize {
    let c = n.saturating_add(1);
    n.saturating_mul(n)
        .saturating_add(m.saturating_mul(n).saturating_mul(2))
        .saturating_add(n.saturating_mul(3))
        .saturating_add(c.saturating_mul(7))
        .saturating_add(c.saturating_mul(c))
}

/// Length of the index workspace: `2 (n + 1) + m + n` (saturating).
pub const fn index_len(n: usize, m: usize) -> usize {
    n.saturating_add(1)
        .saturating_mul(2)
        .saturating_add(m)
        .saturating_add(n)
}

/// The dual active-set solver on caller-owned workspaces (see
/// [`scalar_len`], [`index_len`]). Set up once per `H` and `G`; solved
/// for any `q` and bounds.
#[derive(Debug)]
pub struct QpSolver<'w, S> {
    pub(crate) n: usize,
    pub(crate) m: usize,
    pub(crate) settings: QpSettings,
    /// `H^-1` (symmetric), `n x n` row-major: row `i` is the vector of the
    /// bound on `z_i`.
    pub(crate) hinv: &'w mut [S],
    /// The rows `g_j` of `G`, `m x n`.
    pub(crate) g: &'w mut [S],
    /// `w_j = H^-1 g_j` for each row, `m x n`.
    pub(crate) w: &'w mut [S],
    /// `z_unc = -H^-1 q`, `n`.
    pub(crate) zunc: &'w mut [S],
    /// The primal point `z`, `n`.
    pub(crate) z: &'w mut [S],
    /// Set-up scratch (the pivots of `H`, then their reciprocals), `n`.
    pub(crate) work: &'w mut [S],
    /// The active set's LDL' factor, `(n+1) x (n+1)` row-major, unit lower.
    pub(crate) lf: &'w mut [S],
    pub(crate) df: &'w mut [S],
    pub(crate) mu: &'w mut [S],
    pub(crate) mustar: &'w mut [S],
    pub(crate) tmp: &'w mut [S],
    pub(crate) wv: &'w mut [S],
    /// `g_p' z_unc - b_p` of each active position (fixed during a solve).
    pub(crate) rhs: &'w mut [S],
    /// `L^-1 rhs`, valid for the positions below `fwd_valid`.
    pub(crate) fwd: &'w mut [S],
    /// Active constraint at each position, its side (1 = upper).
    pub(crate) active: &'w mut [usize],
    pub(crate) side: &'w mut [usize],
    /// Position + 1 of each constraint in the active list, 0 if inactive.
    pub(crate) pos: &'w mut [usize],
    pub(crate) count: usize,
    pub(crate) fwd_valid: usize,
    pub(crate) ptol: S,
    pub(crate) dtol: S,
    pub(crate) pivtol: S,
}

/// What [`QpSolver::park`] keeps of a solver besides its workspaces.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Parked {
    n: usize,
    m: usize,
    settings: QpSettings,
    count: usize,
    fwd_valid: usize,
}

/// The solver's slices carved from the workspaces `$scalars` and
/// `$indices` (a short one is a [`QpError::Dimension`], returned from the
/// enclosing function), then `$prepare` with the active-position,
/// primal-point and constraint-row slices bound to the three names, then
/// the solver with no constraint active; the other contents untouched. A
/// macro rather than a function: [`QpSolver::new`] stays one straight
/// body (with a shared function, the f32 firmware's `main`, where `new` is
/// inlined, showed the pinned nightly's bug 2, a multiply's `r0` lost to
/// an SREG save; docs/avr-qp.md, and the HIL tests' miscompile scan).
macro_rules! carve {
    ($n:ident, $m:ident, $settings:ident, $scalars:expr, $indices:expr,
     |$pos:ident, $z:ident, $g:ident| $prepare:block) => {{
        let c = $n + 1;
        let mut buf = $scalars;
        let hinv = take(&mut buf, $n * $n)?;
        let $g = take(&mut buf, $m * $n)?;
        let w = take(&mut buf, $m * $n)?;
        let zunc = take(&mut buf, $n)?;
        let $z = take(&mut buf, $n)?;
        let work = take(&mut buf, $n)?;
        let lf = take(&mut buf, c * c)?;
        let df = take(&mut buf, c)?;
        let mu = take(&mut buf, c)?;
        let mustar = take(&mut buf, c)?;
        let tmp = take(&mut buf, c)?;
        let wv = take(&mut buf, c)?;
        let rhs = take(&mut buf, c)?;
        let fwd = take(&mut buf, c)?;
        let mut ibuf = $indices;
        let active = take(&mut ibuf, c)?;
        let side = take(&mut ibuf, c)?;
        let $pos = take(&mut ibuf, $m + $n)?;
        $prepare
        QpSolver {
            n: $n,
            m: $m,
            settings: $settings,
            hinv,
            g: $g,
            w,
            zunc,
            z: $z,
            work,
            lf,
            df,
            mu,
            mustar,
            tmp,
            wv,
            rhs,
            fwd,
            active,
            side,
            pos: $pos,
            count: 0,
            fwd_valid: 0,
            ptol: S::from_f64($settings.primal_tol),
            dtol: S::from_f64($settings.dual_tol),
            pivtol: S::from_f64($settings.pivot_tol),
        }
    }};
}

/// The first `len` entries of `buf`, which keeps the rest (`Dimension`
/// if it is shorter: [`QpSolver::new`] checked the lengths before).
fn take<'a, T>(buf: &mut &'a mut [T], len: usize) -> Result<&'a mut [T], QpError> {
    let whole = core::mem::take(buf);
    let found = whole.len();
    let (head, tail) = whole.split_at_mut_checked(len).ok_or(QpError::Dimension {
        expected: len,
        found,
    })?;
    *buf = tail;
    Ok(head)
}

pub(crate) fn check_len(expected: usize, found: usize) -> Result<(), QpError> {
    if expected == found {
        Ok(())
    } else {
        Err(QpError::Dimension { expected, found })
    }
}

pub(crate) fn dot<S: QpScalar>(a: &[S], b: &[S]) -> S {
    S::dot(a, b)
}

/// Reads and writes of the workspace by index without a panic path. Every
/// index the solver forms is in range by its invariants (the sizes are
/// checked once, in [`QpSolver::new`]), but the compiler cannot see it and
/// would link a bounds-check panic into firmware; out of range, a read is
/// the default (zero) and a write does nothing (never reached). For the
/// number and the index workspaces alike.
pub(crate) trait Slots<T> {
    /// Entry `i`.
    fn at(&self, i: usize) -> T;
    /// Sets entry `i`.
    fn put(&mut self, i: usize, v: T);
}

impl<T: Copy + Default> Slots<T> for [T] {
    #[inline(always)]
    fn at(&self, i: usize) -> T {
        self.get(i).copied().unwrap_or_default()
    }
    #[inline(always)]
    fn put(&mut self, i: usize, v: T) {
        if let Some(x) = self.get_mut(i) {
            *x = v;
        }
    }
}

impl<'w, S: QpScalar> QpSolver<'w, S> {
    /// Sets up the solver for `H` (`n x n`, row-major, symmetric positive
    /// definite; only its lower triangle is read) and `G` (`m x n`,
    /// row-major; `m` may be 0): the LDL' factorisation of `H` and the
    /// constraints in its coordinates, `O(n^3 + m n^2)`.
    ///
    /// The workspaces must be at least [`scalar_len`]`(n, m)` and
    /// [`index_len`]`(n, m)` long.
    pub fn new(
        n: usize,
        m: usize,
        h: &[S],
        g: &[S],
        settings: QpSettings,
        scalars: &'w mut [S],
        indices: &'w mut [usize],
    ) -> Result<Self, QpError> {
        settings.validate()?;
        if n == 0 {
            return Err(QpError::Dimension {
                expected: 1,
                found: 0,
            });
        }
        if scalars.len() < scalar_len(n, m) {
            return Err(QpError::Dimension {
                expected: scalar_len(n, m),
                found: scalars.len(),
            });
        }
        // From here on every size below fits (it is at most scalar_len).
        check_len(n * n, h.len())?;
        check_len(m * n, g.len())?;
        if indices.len() < index_len(n, m) {
            return Err(QpError::Dimension {
                expected: index_len(n, m),
                found: indices.len(),
            });
        }
        if !h.iter().chain(g.iter()).all(|v| v.is_finite()) {
            return Err(QpError::NonFinite);
        }
        let mut s = carve!(n, m, settings, scalars, indices, |pos, z, gs| {
            pos.fill(0);
            z.fill(S::ZERO);
            for (o, &v) in gs.iter_mut().zip(g) {
                *o = v;
            }
        });
        s.factor_h(h)?;
        s.invert_h();
        s.transform_rows();
        Ok(s)
    }

    /// Ends the borrow of the workspaces, keeping what is not in them (the
    /// sizes, settings and active-set length), so that [`Self::resume`]
    /// can take the same workspaces up again without a new set-up: for a
    /// solver that owns its workspaces (`ActiveSetSolver`).
    #[cfg_attr(not(feature = "mpc"), allow(dead_code))]
    pub(crate) fn park(self) -> Parked {
        Parked {
            n: self.n,
            m: self.m,
            settings: self.settings,
            count: self.count,
            fwd_valid: self.fwd_valid,
        }
    }

    /// The solver [`Self::park`] gave `parked` from, on the same
    /// workspaces: `scalars` and `indices` must be the ones it borrowed,
    /// unchanged since (its set-up and active set live there); other
    /// contents give meaningless numbers (never a panic).
    #[cfg_attr(not(feature = "mpc"), allow(dead_code))]
    pub(crate) fn resume(
        parked: Parked,
        scalars: &'w mut [S],
        indices: &'w mut [usize],
    ) -> Result<Self, QpError> {
        let (n, m, settings) = (parked.n, parked.m, parked.settings);
        let mut s = carve!(n, m, settings, scalars, indices, |_pos, _z, _g| {});
        s.count = parked.count;
        s.fwd_valid = parked.fwd_valid;
        Ok(s)
    }

    /// LDL' of `H` into `lf` (as `n x n` scratch), the pivots into `work`.
    fn factor_h(&mut self, h: &[S]) -> Result<(), QpError> {
        let n = self.n;
        let l = &mut *self.lf;
        l.fill(S::ZERO);
        for j in 0..n {
            let mut d = h.at(j * n + j);
            for k in 0..j {
                let ljk = l.at(j * n + k);
                d -= ljk * ljk * self.work.at(k);
            }
            if d <= S::ZERO || !d.is_finite() {
                return Err(QpError::NotPositiveDefinite);
            }
            self.work.put(j, d);
            l.put(j * n + j, S::ONE);
            for i in j + 1..n {
                let mut v = h.at(i * n + j);
                for k in 0..j {
                    v -= l.at(i * n + k) * l.at(j * n + k) * self.work.at(k);
                }
                l.put(i * n + j, v / d);
            }
        }
        Ok(())
    }

    /// `H^-1 = L^-T D^-1 L^-1` column by column (`L` in `lf`, `D` in
    /// `work`, replaced by `D^-1`: `n` divisions in all). Column `c` needs
    /// only its entries `c..n` (the rest follow by symmetry), and each of
    /// those only the ones below it: about `n^3 / 2` multiply-adds.
    fn invert_h(&mut self) {
        let n = self.n;
        for d in self.work.iter_mut() {
            *d = S::ONE / *d;
        }
        let l = &*self.lf;
        for (c, x) in self.hinv.chunks_exact_mut(n.max(1)).enumerate() {
            // L x = e_c (x_i = 0 above c), scaled by D^-1, then L' x = that
            // for the entries c.. only.
            x.fill(S::ZERO);
            x.put(c, S::ONE);
            for i in c + 1..n {
                let mut v = S::ZERO;
                for k in c..i {
                    v -= l.at(i * n + k) * x.at(k);
                }
                x.put(i, v);
            }
            for (xi, &dinv) in x.iter_mut().zip(self.work.iter()).skip(c) {
                *xi *= dinv;
            }
            for i in (c..n).rev() {
                let mut v = x.at(i);
                for k in i + 1..n {
                    v -= l.at(k * n + i) * x.at(k);
                }
                x.put(i, v);
            }
        }
        // Row c holds H^-1[c][c..]: mirror it into the entries above.
        for c in 0..n {
            for i in c + 1..n {
                let v = self.hinv.at(c * n + i);
                self.hinv.put(i * n + c, v);
            }
        }
    }

    /// `w_j = H^-1 g_j`.
    fn transform_rows(&mut self) {
        let n = self.n;
        let n = n.max(1);
        for (wj, gj) in self.w.chunks_exact_mut(n).zip(self.g.chunks_exact(n)) {
            for (wi, row) in wj.iter_mut().zip(self.hinv.chunks_exact(n)) {
                *wi = dot(row, gj);
            }
        }
    }

    /// The number of variables `n`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The number of rows of `G`, `m`.
    pub fn m(&self) -> usize {
        self.m
    }

    /// The settings the solver was set up with.
    pub fn settings(&self) -> &QpSettings {
        &self.settings
    }

    /// Constraint `j`'s vector `H^-1 g_j` (`w_j` for a row, row `i` of
    /// `H^-1` for the bound on `z_i`).
    #[inline]
    pub(crate) fn wvec(&self, j: usize) -> &[S] {
        let n = self.n;
        let (src, r) = if j < self.m {
            (&*self.w, j)
        } else {
            (&*self.hinv, j - self.m)
        };
        src.get(r * n..(r + 1) * n).unwrap_or(&[])
    }

    /// Constraint `j`'s value `g_j' x` at `x` (`x_i` for the bound on
    /// `z_i`).
    #[inline]
    pub(crate) fn value(&self, j: usize, x: &[S]) -> S {
        let n = self.n;
        if j < self.m {
            dot(self.g.get(j * n..(j + 1) * n).unwrap_or(&[]), x)
        } else {
            x.get(j - self.m).copied().unwrap_or(S::ZERO)
        }
    }

    /// The entry `g_i' H^-1 g_j` of `M` for constraints `i` and `j`: an
    /// entry of `H^-1` or of a `w_j` when a bound takes part, `O(1)`.
    #[inline]
    pub(crate) fn m_entry(&self, i: usize, j: usize) -> S {
        let (n, m) = (self.n, self.m);
        let at = |v: &[S], k: usize| v.get(k).copied().unwrap_or(S::ZERO);
        match (i < m, j < m) {
            (false, false) => at(self.hinv, (i - m) * n + (j - m)),
            (true, false) => at(self.w, i * n + (j - m)),
            (false, true) => at(self.w, j * n + (i - m)),
            (true, true) => self.value(i, self.wvec(j)),
        }
    }

    pub(crate) fn bounds(data: &QpData<'_, S>, m: usize, j: usize) -> (S, S) {
        if j < m {
            (data.l.at(j), data.u.at(j))
        } else {
            (data.lb.at(j - m), data.ub.at(j - m))
        }
    }

    /// The current active set, in the order it was built.
    pub fn active_set(&self) -> impl Iterator<Item = ActiveConstraint> + '_ {
        self.active
            .iter()
            .zip(self.side.iter())
            .take(self.count)
            .map(|(&index, &s)| ActiveConstraint {
                index,
                side: if s & 1 == 0 { Side::Lower } else { Side::Upper },
            })
    }

    /// Sets the active set the next [`Start::Warm`] solve starts from.
    /// Indices must be below `m + n`, distinct, and at most `n` of them.
    pub fn set_active_set(&mut self, set: &[ActiveConstraint]) -> Result<(), QpError> {
        if set.len() > self.n {
            return Err(QpError::InvalidActiveSet);
        }
        self.clear();
        for (p, a) in set.iter().enumerate() {
            if a.index >= self.m + self.n || self.pos.at(a.index) != 0 {
                self.clear();
                return Err(QpError::InvalidActiveSet);
            }
            self.active.put(p, a.index);
            self.side.put(p, usize::from(a.side == Side::Upper));
            self.pos.put(a.index, p + 1);
            self.count = p + 1;
        }
        Ok(())
    }

    pub(crate) fn clear(&mut self) {
        for &j in self.active.iter().take(self.count) {
            self.pos.put(j, 0);
        }
        self.count = 0;
        self.fwd_valid = 0;
    }

    /// The largest entry of `L D L' - A_A D^-1 A_A'` (the updated factor
    /// against `M` formed from scratch), relative to the largest of `M`.
    #[cfg(test)]
    pub(crate) fn factor_residual(&self) -> f64 {
        let (c, k) = (self.n + 1, self.count);
        let (mut worst, mut scale) = (0.0_f64, 0.0_f64);
        for i in 0..k {
            for j in 0..=i {
                let mut ldl = 0.0;
                for t in 0..=j {
                    let li = if t == i {
                        1.0
                    } else {
                        self.lf[i * c + t].to_f64()
                    };
                    let lj = if t == j {
                        1.0
                    } else {
                        self.lf[j * c + t].to_f64()
                    };
                    ldl += li * self.df[t].to_f64() * lj;
                }
                // g_a' H^-1 g_b in f64 from G and H^-1 (not the w_j).
                let n = self.n;
                let row = |c: usize, t: usize| -> f64 {
                    if c < self.m {
                        self.g[c * n + t].to_f64()
                    } else {
                        f64::from(u8::from(c - self.m == t))
                    }
                };
                let (a, b) = (self.active[i], self.active[j]);
                let mut m = 0.0;
                for r in 0..n {
                    for t in 0..n {
                        m += row(a, r) * self.hinv[r * n + t].to_f64() * row(b, t);
                    }
                }
                worst = worst.max((ldl - m).abs());
                scale = scale.max(m.abs());
            }
        }
        worst / scale.max(f64::MIN_POSITIVE)
    }

    /// The solution `z` of the last successful solve into `z` (`n`).
    pub fn solution(&self, z: &mut [S]) -> Result<(), QpError> {
        check_len(self.n, z.len())?;
        for (o, &v) in z.iter_mut().zip(self.z.iter()) {
            *o = v;
        }
        Ok(())
    }

    /// The multipliers of the last successful solve into `out` (`m + n`:
    /// rows of `G`, then bounds), signed: positive at an upper bound,
    /// negative at a lower one, zero when inactive. They satisfy
    /// `H z + q + G' mu_G + mu_b = 0`.
    pub fn multipliers(&self, out: &mut [S]) -> Result<(), QpError> {
        check_len(self.m + self.n, out.len())?;
        out.fill(S::ZERO);
        for (&j, &mu) in self.active.iter().zip(self.mu.iter()).take(self.count) {
            if let Some(o) = out.get_mut(j) {
                *o = mu;
            }
        }
        Ok(())
    }
}
