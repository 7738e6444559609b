//! The dual active-set solver: set-up (LDL' of `H`, the constraints in its
//! coordinates) and the Goldfarb-Idnani iterations with LDL' updates of the
//! active constraints' `M = G_A H^-1 G_A'`.
//!
//! Coordinates: with `H = L D L'` (unit lower `L`) and `y = L' z`, the QP is
//! `min 1/2 y'Dy + (L^-1 q)'y` s.t. `lo <= a_j'y <= hi`, where `a_j =
//! L^-1 g_j` for a row of `G` and `a_j = L^-1 e_i` (column `i` of `L^-1`) for
//! the bound on `z_i`: simple bounds need no row of `G`. With signed
//! multipliers `mu` (positive at an upper bound, negative at a lower one),
//! `y = y_unc - D^-1 A_A' mu` and `M mu = A_A y_unc - b_A`.

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
/// `n^2 + m n + 5 n + 5 (n + 1) + (n + 1)^2` (saturating at `usize::MAX`,
/// which no slice reaches: sizes too large for the address space, as on a
/// 16-bit AVR, are refused by [`QpSolver::new`] instead of wrapping).
pub const fn scalar_len(n: usize, m: usize) -> usize {
    let c = n.saturating_add(1);
    n.saturating_mul(n)
        .saturating_add(m.saturating_mul(n))
        .saturating_add(n.saturating_mul(5))
        .saturating_add(c.saturating_mul(5))
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
    /// `L^-T` (upper triangular), row `i` = column `i` of `L^-1`, `n x n`.
    pub(crate) linvt: &'w mut [S],
    /// `1 / D`, `n`.
    pub(crate) dinv: &'w mut [S],
    /// `L^-1 G'` as rows `a_j`, `m x n`.
    pub(crate) rows: &'w mut [S],
    /// `L^-1 q`, then scratch `D^-1 a_k`.
    pub(crate) qt: &'w mut [S],
    pub(crate) work: &'w mut [S],
    pub(crate) yunc: &'w mut [S],
    pub(crate) y: &'w mut [S],
    /// The active set's LDL' factor, `(n+1) x (n+1)` row-major, unit lower.
    pub(crate) lf: &'w mut [S],
    pub(crate) df: &'w mut [S],
    pub(crate) mu: &'w mut [S],
    pub(crate) mustar: &'w mut [S],
    pub(crate) tmp: &'w mut [S],
    pub(crate) wv: &'w mut [S],
    /// Active constraint at each position, its side (1 = upper).
    pub(crate) active: &'w mut [usize],
    pub(crate) side: &'w mut [usize],
    /// Position + 1 of each constraint in the active list, 0 if inactive.
    pub(crate) pos: &'w mut [usize],
    pub(crate) count: usize,
    pub(crate) ptol: S,
    pub(crate) dtol: S,
    pub(crate) pivtol: S,
}

fn take<'a, T>(buf: &mut &'a mut [T], len: usize) -> &'a mut [T] {
    let (head, tail) = core::mem::take(buf).split_at_mut(len);
    *buf = tail;
    head
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
        let c = n + 1;
        let mut buf = scalars;
        let linvt = take(&mut buf, n * n);
        let dinv = take(&mut buf, n);
        let rows = take(&mut buf, m * n);
        let qt = take(&mut buf, n);
        let work = take(&mut buf, n);
        let yunc = take(&mut buf, n);
        let y = take(&mut buf, n);
        let lf = take(&mut buf, c * c);
        let df = take(&mut buf, c);
        let mu = take(&mut buf, c);
        let mustar = take(&mut buf, c);
        let tmp = take(&mut buf, c);
        let wv = take(&mut buf, c);
        let mut ibuf = indices;
        let active = take(&mut ibuf, c);
        let side = take(&mut ibuf, c);
        let pos = take(&mut ibuf, m + n);
        pos.fill(0);
        let mut s = QpSolver {
            n,
            m,
            settings,
            linvt,
            dinv,
            rows,
            qt,
            work,
            yunc,
            y,
            lf,
            df,
            mu,
            mustar,
            tmp,
            wv,
            active,
            side,
            pos,
            count: 0,
            ptol: S::from_f64(settings.primal_tol),
            dtol: S::from_f64(settings.dual_tol),
            pivtol: S::from_f64(settings.pivot_tol),
        };
        s.factor_h(h)?;
        s.transform_rows(g);
        Ok(s)
    }

    /// LDL' of `H` into `lf` (as `n x n` scratch), then `L^-T` and `1/D`.
    fn factor_h(&mut self, h: &[S]) -> Result<(), QpError> {
        let n = self.n;
        let l = &mut self.lf[..n * n];
        l.fill(S::ZERO);
        for j in 0..n {
            let mut d = h[j * n + j];
            for k in 0..j {
                let ljk = l[j * n + k];
                d -= ljk * ljk * self.work[k];
            }
            if d <= S::ZERO || !d.is_finite() {
                return Err(QpError::NotPositiveDefinite);
            }
            self.work[j] = d;
            l[j * n + j] = S::ONE;
            for i in j + 1..n {
                let mut v = h[i * n + j];
                for k in 0..j {
                    v -= l[i * n + k] * l[j * n + k] * self.work[k];
                }
                l[i * n + j] = v / d;
            }
        }
        for (di, d) in self.dinv.iter_mut().zip(self.work.iter()) {
            *di = S::ONE / *d;
        }
        // Column c of L^-1 (entries c.. n) into row c of linvt.
        self.linvt.fill(S::ZERO);
        for c in 0..n {
            self.linvt[c * n + c] = S::ONE;
            for i in c + 1..n {
                let mut v = S::ZERO;
                for k in c..i {
                    v -= l[i * n + k] * self.linvt[c * n + k];
                }
                self.linvt[c * n + i] = v;
            }
        }
        Ok(())
    }

    /// `a_j = L^-1 g_j` by forward substitution (`L` still in `lf`).
    fn transform_rows(&mut self, g: &[S]) {
        let n = self.n;
        let l = &self.lf[..n * n];
        for (a, gj) in self.rows.chunks_exact_mut(n).zip(g.chunks_exact(n)) {
            for k in 0..n {
                let mut v = gj[k];
                for i in 0..k {
                    v -= l[k * n + i] * a[i];
                }
                a[k] = v;
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

    /// Constraint `j`'s vector `a_j` in the factor's coordinates.
    pub(crate) fn vector(&self, j: usize) -> &[S] {
        let n = self.n;
        if j < self.m {
            &self.rows[j * n..(j + 1) * n]
        } else {
            let i = j - self.m;
            &self.linvt[i * n..(i + 1) * n]
        }
    }

    pub(crate) fn bounds(data: &QpData<'_, S>, m: usize, j: usize) -> (S, S) {
        if j < m {
            (data.l[j], data.u[j])
        } else {
            (data.lb[j - m], data.ub[j - m])
        }
    }

    /// The current active set, in the order it was built.
    pub fn active_set(&self) -> impl Iterator<Item = ActiveConstraint> + '_ {
        self.active[..self.count]
            .iter()
            .zip(self.side[..self.count].iter())
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
            if a.index >= self.m + self.n || self.pos[a.index] != 0 {
                self.clear();
                return Err(QpError::InvalidActiveSet);
            }
            self.active[p] = a.index;
            self.side[p] = usize::from(a.side == Side::Upper);
            self.pos[a.index] = p + 1;
            self.count = p + 1;
        }
        Ok(())
    }

    pub(crate) fn clear(&mut self) {
        for &j in &self.active[..self.count] {
            self.pos[j] = 0;
        }
        self.count = 0;
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
                let (ai, aj) = (self.vector(self.active[i]), self.vector(self.active[j]));
                let m: f64 = (0..self.n)
                    .map(|t| ai[t].to_f64() * self.dinv[t].to_f64() * aj[t].to_f64())
                    .sum();
                worst = worst.max((ldl - m).abs());
                scale = scale.max(m.abs());
            }
        }
        worst / scale.max(f64::MIN_POSITIVE)
    }

    /// The solution `z` of the last successful solve into `z` (`n`).
    pub fn solution(&self, z: &mut [S]) -> Result<(), QpError> {
        check_len(self.n, z.len())?;
        for (zi, row) in z.iter_mut().zip(self.linvt.chunks_exact(self.n)) {
            *zi = dot(row, self.y);
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
        for (&j, &mu) in self.active[..self.count].iter().zip(self.mu.iter()) {
            if let Some(o) = out.get_mut(j) {
                *o = mu;
            }
        }
        Ok(())
    }
}
