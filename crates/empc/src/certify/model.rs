//! The mpQP in the solver's form with every quantity the certification
//! needs as an affine function of the normalised parameter `s` (`theta =
//! centre + half * s`, the parameter box becoming `[-1, 1]^p`).
//!
//! An affine function is a vector of `d + 1` numbers: the coefficients of
//! the `d` LP variables, then the constant. Cold start: `d = p`, the
//! variables are `s`. Warm start: `d = 2 p`, `(s, s_prev)`: the solver's
//! data depend on `s` only, the previous parameter enters through the
//! start region.

use core::cmp::Ordering;
use kestrel_qp::QpSettings;
use kestrel_qp::parametric::{Affine, ParametricQp};
use nalgebra::DMatrix;

use super::geometry::{Geometry, Half, Poly, half, size};

/// `y += a x`.
pub(super) fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (u, v) in y.iter_mut().zip(x) {
        *u += a * v;
    }
}

/// Side codes as the solver keeps them: bit 0 the upper side, bit 1 an
/// equality row.
pub(super) const UPPER: u8 = 1;
/// See [`UPPER`].
pub(super) const EQUALITY: u8 = 2;

/// The sign of a side code's multiplier (`+1` upper, `-1` lower).
pub(super) fn sign(code: u8) -> f64 {
    if code & UPPER != 0 { 1.0 } else { -1.0 }
}

/// The problem data of the certification.
#[derive(Debug, Clone)]
pub(super) struct Model {
    /// Variables.
    pub n: usize,
    /// Constraints (rows of the solver's `G`, then the `n` bounds).
    pub ncons: usize,
    /// Rows of the solver's `G` (constraint `j >= rows` bounds `z_{j-rows}`).
    pub rows: usize,
    /// Parameters.
    pub p: usize,
    /// LP variables (`p` or `2 p`).
    pub d: usize,
    /// Box centre and half-widths of `theta`.
    pub centre: Vec<f64>,
    /// See [`Self::centre`].
    pub half: Vec<f64>,
    /// `g_a' H^-1 g_b` of every pair of constraints, `ncons x ncons`.
    pub mm: DMatrix<f64>,
    /// `g_j' z_unc(s)` of each constraint (`z_unc = -H^-1 q`).
    pub gz: Vec<Vec<f64>>,
    /// Lower and upper bound of each constraint, `None` if infinite.
    pub lo: Vec<Option<Vec<f64>>>,
    /// See [`Self::lo`].
    pub hi: Vec<Option<Vec<f64>>>,
    /// Whether a constraint is an equality row (`l = u` as functions).
    pub equality: Vec<bool>,
    /// The extra parameter polytope's rows (`theta_poly`), each `f(s) <= 0`
    /// in the normalised parameter (`p + 1` entries); empty for a box.
    pub param: Vec<Vec<f64>>,
    /// The solver settings whose rules are mirrored.
    pub settings: QpSettings,
    /// Merged mode (`crate::certify::merge`): the active list is a
    /// canonical order, not the solver's, so a tie between identical
    /// functions takes both outcomes and a removal costs the most any
    /// position could ([`Self::position`]); it sets [`Self::canonical`] too.
    pub merge: bool,
    /// A full dual step stops at its canonical state
    /// ([`super::step::Outcome::Canonical`]): merged and union-merge modes.
    pub canonical: bool,
}

impl Model {
    /// Builds the model of `par` with `d` LP variables (`p` or `2 p`).
    pub fn new(par: &ParametricQp, d: usize, settings: QpSettings) -> Option<Self> {
        let (n, m, p) = (par.n(), par.m(), par.p());
        let ncons = m + n;
        let centre: Vec<f64> = (0..p)
            .map(|k| 0.5 * (par.theta_lb()[k] + par.theta_ub()[k]))
            .collect();
        let half: Vec<f64> = (0..p)
            .map(|k| 0.5 * (par.theta_ub()[k] - par.theta_lb()[k]))
            .collect();
        // `a` in the normalised parameter, as a function of `vars` LP
        // variables (`s` first; the constant last).
        let normalised = |a: &Affine, vars: usize| -> Vec<f64> {
            let mut f = vec![0.0; vars + 1];
            for k in 0..p {
                f[k] = a.e[k] * half[k];
            }
            f[vars] = a.c + a.e.iter().zip(&centre).map(|(e, c)| e * c).sum::<f64>();
            f
        };
        let to_s = |a: &Affine| normalised(a, d);
        let h = DMatrix::from_row_slice(n, n, par.h());
        let hinv = h.cholesky()?.inverse();
        let g = DMatrix::from_fn(ncons, n, |j, i| par.constraint_row(j)[i]);
        let hg = &hinv * g.transpose(); // n x ncons
        let mm = &g * &hg;
        // z_unc = -H^-1 q(s).
        let q: Vec<Vec<f64>> = (0..n).map(|i| to_s(par.q(i))).collect();
        let zunc: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                let mut f = vec![0.0; d + 1];
                for (k, qk) in q.iter().enumerate() {
                    axpy(&mut f, -hinv[(i, k)], qk);
                }
                f
            })
            .collect();
        let gz = (0..ncons)
            .map(|j| {
                let mut f = vec![0.0; d + 1];
                for (i, zi) in zunc.iter().enumerate() {
                    axpy(&mut f, g[(j, i)], zi);
                }
                f
            })
            .collect();
        let lo: Vec<Option<Vec<f64>>> = (0..ncons).map(|j| par.lower(j).map(to_s)).collect();
        let hi: Vec<Option<Vec<f64>>> = (0..ncons).map(|j| par.upper(j).map(to_s)).collect();
        let equality = (0..ncons)
            .map(|j| matches!((par.lower(j), par.upper(j)), (Some(a), Some(b)) if a == b))
            .collect();
        let param = par.theta_rows().iter().map(|a| normalised(a, p)).collect();
        Some(Model {
            n,
            ncons,
            rows: m,
            p,
            d,
            centre,
            half,
            mm,
            gz,
            lo,
            hi,
            equality,
            param,
            settings,
            merge: false,
            canonical: false,
        })
    }

    /// The solver position the flop model charges for removing list
    /// position `p`: `p` itself, or 0 in merged mode and on a region whose
    /// list order is one of several (`mixed`, union-merge mode): the
    /// solver's order is unknown there; removing the first position costs
    /// the most and invalidates the whole kept forward solve.
    pub fn position(&self, p: usize, mixed: bool) -> usize {
        if self.merge || mixed { 0 } else { p }
    }

    /// The extra parameter polytope as half-spaces of `d` LP variables,
    /// on the `p` of them from `offset` (0: `s`; `p`: `s_prev`).
    pub fn param_halfs(&self, offset: usize, d: usize) -> Vec<Half> {
        let p = self.p;
        self.param
            .iter()
            .map(|f| {
                let mut g = vec![0.0; d + 1];
                g[offset..offset + p].copy_from_slice(&f[..p]);
                g[d] = f[p];
                half(&g, false, size(f))
            })
            .collect()
    }

    /// The parameter set in the LP variables: the cube, cut by the extra
    /// polytope for `s` (and for `s_prev` when `d = 2 p`); `None` if it has
    /// no ball of radius `min_radius`.
    pub fn parameter_set(&self, geo: &mut Geometry) -> Option<Poly> {
        let mut hs = self.param_halfs(0, self.d);
        if self.d == 2 * self.p {
            hs.extend(self.param_halfs(self.p, self.d));
        }
        geo.restrict(&Poly::cube(self.d), &hs)
    }

    /// The active bound of constraint `j` on side `code`.
    pub fn bound(&self, j: usize, code: u8) -> Option<&Vec<f64>> {
        if code & UPPER != 0 {
            self.hi[j].as_ref()
        } else {
            self.lo[j].as_ref()
        }
    }

    /// `M = G_A H^-1 G_A'` of an active list.
    pub fn m_of(&self, active: &[(usize, u8)]) -> DMatrix<f64> {
        let k = active.len();
        DMatrix::from_fn(k, k, |a, b| self.mm[(active[a].0, active[b].0)])
    }

    /// Solves `M X = R` (`M` of an independent active list, `R` `k x c`).
    pub fn solve_m(&self, m: &DMatrix<f64>, r: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        match m.clone().cholesky() {
            Some(c) => Some(c.solve(r)),
            None => m.clone().lu().solve(r),
        }
    }

    /// `mu*(s) = M^-1 (A_A y_unc - b_A)` of an independent active list, one
    /// affine function per position.
    pub fn mustar(&self, active: &[(usize, u8)]) -> Option<Vec<Vec<f64>>> {
        let k = active.len();
        if k == 0 {
            return Some(Vec::new());
        }
        let d = self.d;
        let mut r = DMatrix::zeros(k, d + 1);
        for (a, &(j, code)) in active.iter().enumerate() {
            let b = self.bound(j, code)?;
            for c in 0..=d {
                r[(a, c)] = self.gz[j][c] - b[c];
            }
        }
        let x = self.solve_m(&self.m_of(active), &r)?;
        Some((0..k).map(|a| x.row(a).iter().copied().collect()).collect())
    }

    /// `M^-1 e_last` of an independent active list.
    pub fn last_column(&self, active: &[(usize, u8)]) -> Option<Vec<f64>> {
        let k = active.len();
        let mut e = DMatrix::zeros(k, 1);
        e[(k - 1, 0)] = 1.0;
        let x = self.solve_m(&self.m_of(active), &e)?;
        Some(x.column(0).iter().copied().collect())
    }

    /// Whether constraint `j` entering after `active` (independent) gets a
    /// zero pivot: `n` constraints are active already, or the solver's test
    /// `d > pivot_tol * diag` fails for the Schur complement `d = diag - t'
    /// M^-1 t`, `diag = g_j' H^-1 g_j`.
    pub fn dependent(&self, active: &[(usize, u8)], j: usize) -> bool {
        if active.len() >= self.n {
            // The solver's rule: `n` independent constraints span everything.
            return true;
        }
        let diag = self.mm[(j, j)];
        if active.is_empty() {
            return diag.partial_cmp(&(self.settings.pivot_tol * diag)) != Some(Ordering::Greater);
        }
        let k = active.len();
        let t = DMatrix::from_fn(k, 1, |a, _| self.mm[(active[a].0, j)]);
        let Some(x) = self.solve_m(&self.m_of(active), &t) else {
            return true;
        };
        let d = diag - t.column(0).dot(&x.column(0));
        d.partial_cmp(&(self.settings.pivot_tol * diag)) != Some(Ordering::Greater)
    }

    /// The null vector `p` of `M` (last entry 1) when the last of `active`
    /// depends on the others: `M_{11} x = -M_{1,last}`.
    pub fn null_vector(&self, active: &[(usize, u8)]) -> Option<Vec<f64>> {
        let k = active.len();
        let head = &active[..k - 1];
        let mut out = vec![0.0; k];
        out[k - 1] = 1.0;
        if k > 1 {
            let rhs = DMatrix::from_fn(k - 1, 1, |a, _| -self.mm[(head[a].0, active[k - 1].0)]);
            let x = self.solve_m(&self.m_of(head), &rhs)?;
            out[..k - 1].copy_from_slice(x.as_slice());
        }
        Some(out)
    }

    /// `g_j' z(s)` at the primal point of multipliers `mu` (one affine
    /// function per active position): `g_j' z_unc - sum_p (g_j' H^-1
    /// g_{A_p}) mu_p`.
    pub fn value(&self, j: usize, active: &[(usize, u8)], mu: &[Vec<f64>]) -> Vec<f64> {
        let mut f = self.gz[j].clone();
        for (&(a, _), m) in active.iter().zip(mu) {
            axpy(&mut f, -self.mm[(j, a)], m);
        }
        f
    }

    /// `theta` of a normalised point's first `p` entries (`offset` 0) or
    /// of its previous-parameter part (`offset` `p`).
    pub fn theta(&self, x: &[f64], offset: usize) -> Vec<f64> {
        (0..self.p)
            .map(|k| self.centre[k] + self.half[k] * x[offset + k])
            .collect()
    }
}

/// A constraint's name in paths and reports: `r<j>` for row `j` of the
/// solver's `G`, `b<i>` for the bound on `z_i` (`j = m + i`).
pub fn constraint_name(j: usize, m: usize) -> String {
    if j < m {
        format!("r{j}")
    } else {
        format!("b{}", j - m)
    }
}
