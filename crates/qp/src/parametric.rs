//! A `kestrel.mpqp.v1` problem in the solver's form (`std` only).
//!
//! The mpQP `min 1/2 z'Hz + (f + F'theta)'z` s.t. `G z <= W + E theta`
//! ([`MpqpProblem`]) becomes `min 1/2 z'Hz + q'z` s.t. `l <= G_s z <= u`,
//! `lb <= z <= ub` with every entry of `q, l, u, lb, ub` affine in `theta`
//! (or infinite):
//!
//! - a row with one nonzero coefficient `a` on `z_i` is the simple bound
//!   `z_i <= (W_r + E_r theta) / a` (`a > 0`) or `z_i >= ...` (`a < 0`),
//!   no row of `G_s`; a second row bounding the same side of the same
//!   variable is kept as a general row (so every bound stays affine);
//! - a row equal to the negation of an earlier general row with no lower
//!   bound yet becomes that row's lower bound (`-g'z <= r` is `g'z >= -r`),
//!   so mirrored pairs are one double-sided row;
//! - every other row is a one-sided row (`l = -inf`), in mpQP order;
//! - a row identical to an earlier one (`G`, `W` and `E` equal, as move
//!   blocking repeats a block's bounds) is dropped: it maps to the earlier
//!   row's constraint.
//!
//! Solver constraint indices follow [`QpSolver`]: rows of `G_s` first
//! (`0..m`), then the bound on `z_i` at `m + i`.

use crate::{QpData, QpError, QpScalar, QpSettings, QpSolver, Side, index_len, scalar_len};
use kestrel_core::formats::{FormatError, MpqpProblem};
use std::fmt;

/// An affine function of the parameter: `c + e'theta`.
#[derive(Debug, Clone, PartialEq)]
pub struct Affine {
    /// The constant term.
    pub c: f64,
    /// The coefficients of `theta` (`p` entries).
    pub e: Vec<f64>,
}

impl Affine {
    /// The value at `theta` (`p` entries; extra entries are ignored, missing
    /// ones count as 0).
    pub fn eval(&self, theta: &[f64]) -> f64 {
        self.c + self.e.iter().zip(theta).map(|(a, t)| a * t).sum::<f64>()
    }

    fn scaled(c: f64, e: impl Iterator<Item = f64>, s: f64) -> Self {
        Affine {
            c: c * s,
            e: e.map(|v| v * s).collect(),
        }
    }
}

/// Which mpQP rows give a solver constraint its bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RowSource {
    /// The mpQP row of the lower bound, if any.
    pub lower: Option<usize>,
    /// The mpQP row of the upper bound, if any.
    pub upper: Option<usize>,
}

/// Why an mpQP problem cannot be mapped.
#[derive(Debug)]
pub enum ParametricError {
    /// The problem fails [`MpqpProblem::validate`].
    Format(FormatError),
    /// Row `0` of `G` is zero: it constrains no variable.
    ZeroRow(usize),
    /// `theta` has the wrong length.
    Dimension {
        /// The number of parameters `p`.
        expected: usize,
        /// The length given.
        found: usize,
    },
}

impl fmt::Display for ParametricError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParametricError::Format(e) => write!(f, "invalid mpQP problem: {e}"),
            ParametricError::ZeroRow(r) => {
                write!(f, "row {r} of G is zero (it constrains no variable)")
            }
            ParametricError::Dimension { expected, found } => {
                write!(f, "theta has {found} entries, the problem {expected}")
            }
        }
    }
}

impl std::error::Error for ParametricError {}

/// The solver inputs at one parameter value (`q`, `lb`, `ub`: `n`; `l`,
/// `u`: `m`), filled by [`ParametricQp::fill`].
#[derive(Debug, Clone, PartialEq)]
pub struct QpBuffers<S> {
    /// Linear term.
    pub q: Vec<S>,
    /// Lower bounds of the rows.
    pub l: Vec<S>,
    /// Upper bounds of the rows.
    pub u: Vec<S>,
    /// Lower bounds of `z`.
    pub lb: Vec<S>,
    /// Upper bounds of `z`.
    pub ub: Vec<S>,
}

impl<S: QpScalar> QpBuffers<S> {
    /// The buffers as the solver's [`QpData`].
    pub fn data(&self) -> QpData<'_, S> {
        QpData {
            q: &self.q,
            l: &self.l,
            u: &self.u,
            lb: &self.lb,
            ub: &self.ub,
        }
    }
}

/// An mpQP in the solver's form, every input affine in `theta` (see the
/// module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct ParametricQp {
    n: usize,
    p: usize,
    m: usize,
    h: Vec<f64>,
    g: Vec<f64>,
    q: Vec<Affine>,
    lower: Vec<Option<Affine>>,
    upper: Vec<Option<Affine>>,
    sources: Vec<RowSource>,
    /// Solver constraint and side of each mpQP row.
    of_row: Vec<(usize, Side)>,
    theta_lb: Vec<f64>,
    theta_ub: Vec<f64>,
    /// The extra parameter polytope's rows, each `row(theta) <= 0`.
    theta_rows: Vec<Affine>,
}

impl ParametricQp {
    /// Maps `problem` (validated first) to the solver's form.
    pub fn from_mpqp(problem: &MpqpProblem) -> Result<Self, ParametricError> {
        problem.validate().map_err(ParametricError::Format)?;
        let (n, p) = (problem.n(), problem.p());
        let rhs =
            |r: usize, s: f64| Affine::scaled(problem.w[r], (0..p).map(|k| problem.e[(r, k)]), s);
        // General rows: coefficients, lower and upper bound sources.
        let mut g: Vec<f64> = Vec::new();
        let mut general: Vec<RowSource> = Vec::new();
        let mut bound = vec![RowSource::default(); n];
        let mut bound_side: Vec<(usize, usize, Side, f64)> = Vec::new();
        let mut general_rows: Vec<(usize, usize, Side)> = Vec::new();
        // Rows identical to an earlier one (G, W and E) alias it.
        let same = |r: usize, s: usize| {
            problem.g.row(r) == problem.g.row(s)
                && problem.w[r] == problem.w[s]
                && problem.e.row(r) == problem.e.row(s)
        };
        let mut alias: Vec<(usize, usize)> = Vec::new();
        for r in 0..problem.m() {
            let nz: Vec<usize> = (0..n).filter(|&j| problem.g[(r, j)] != 0.0).collect();
            if nz.is_empty() {
                return Err(ParametricError::ZeroRow(r));
            }
            if let Some(s) = (0..r).find(|&s| same(r, s)) {
                alias.push((r, s));
                continue;
            }
            if let [i] = nz[..] {
                let a = problem.g[(r, i)];
                let slot = if a > 0.0 {
                    &mut bound[i].upper
                } else {
                    &mut bound[i].lower
                };
                if slot.is_none() {
                    *slot = Some(r);
                    let side = if a > 0.0 { Side::Upper } else { Side::Lower };
                    bound_side.push((r, i, side, a));
                    continue;
                }
            }
            let row: Vec<f64> = (0..n).map(|j| problem.g[(r, j)]).collect();
            let mirror = (0..general.len()).find(|&k| {
                general[k].lower.is_none()
                    && g[k * n..(k + 1) * n]
                        .iter()
                        .zip(&row)
                        .all(|(a, b)| *a == -*b)
            });
            match mirror {
                Some(k) => {
                    general[k].lower = Some(r);
                    general_rows.push((r, k, Side::Lower));
                }
                None => {
                    general_rows.push((r, general.len(), Side::Upper));
                    general.push(RowSource {
                        lower: None,
                        upper: Some(r),
                    });
                    g.extend(row);
                }
            }
        }
        let m = general.len();
        let mut lower = Vec::with_capacity(m + n);
        let mut upper = Vec::with_capacity(m + n);
        for s in &general {
            lower.push(s.lower.map(|r| rhs(r, -1.0)));
            upper.push(s.upper.map(|r| rhs(r, 1.0)));
        }
        for (i, s) in bound.iter().enumerate() {
            let a = |r: usize| problem.g[(r, i)];
            lower.push(s.lower.map(|r| rhs(r, 1.0 / a(r))));
            upper.push(s.upper.map(|r| rhs(r, 1.0 / a(r))));
        }
        let mut of_row = vec![(0, Side::Upper); problem.m()];
        for &(r, k, side) in &general_rows {
            of_row[r] = (k, side);
        }
        for &(r, i, side, _) in &bound_side {
            of_row[r] = (m + i, side);
        }
        for &(r, s) in &alias {
            of_row[r] = of_row[s];
        }
        let q = (0..n)
            .map(|i| Affine {
                c: problem.f[i],
                e: (0..p).map(|k| problem.f_theta[(k, i)]).collect(),
            })
            .collect();
        let mut sources = general;
        sources.extend(bound);
        Ok(ParametricQp {
            n,
            p,
            m,
            h: (0..n * n).map(|t| problem.h[(t / n, t % n)]).collect(),
            g,
            q,
            lower,
            upper,
            sources,
            of_row,
            theta_lb: problem.theta_lb.iter().copied().collect(),
            theta_ub: problem.theta_ub.iter().copied().collect(),
            theta_rows: problem
                .theta_poly
                .iter()
                .flat_map(|(a, b)| {
                    (0..b.len()).map(move |r| Affine {
                        c: -b[r],
                        e: (0..p).map(|k| a[(r, k)]).collect(),
                    })
                })
                .collect(),
        })
    }

    /// The number of variables `n`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The number of parameters `p`.
    pub fn p(&self) -> usize {
        self.p
    }

    /// The number of general (non-bound) rows `m` of the solver's `G`.
    pub fn m(&self) -> usize {
        self.m
    }

    /// `H`, `n x n`, row-major.
    pub fn h(&self) -> &[f64] {
        &self.h
    }

    /// The solver's `G`, `m x n`, row-major.
    pub fn g(&self) -> &[f64] {
        &self.g
    }

    /// The parameter box's lower corner.
    pub fn theta_lb(&self) -> &[f64] {
        &self.theta_lb
    }

    /// The parameter box's upper corner.
    pub fn theta_ub(&self) -> &[f64] {
        &self.theta_ub
    }

    /// The problem's extra parameter polytope (`theta_poly`, `A theta <=
    /// b`) as affine functions that must be `<= 0` (`a_r' theta - b_r`);
    /// empty when the parameter set is the box alone.
    pub fn theta_rows(&self) -> &[Affine] {
        &self.theta_rows
    }

    /// Whether `theta` lies in the parameter set: the box and the extra
    /// polytope, each row within `tol` (absolute).
    pub fn contains(&self, theta: &[f64], tol: f64) -> bool {
        theta.len() == self.p
            && theta
                .iter()
                .zip(self.theta_lb.iter().zip(&self.theta_ub))
                .all(|(t, (l, u))| *t >= l - tol && *t <= u + tol)
            && self.theta_rows.iter().all(|r| r.eval(theta) <= tol)
    }

    /// `q_i` as an affine function of `theta`.
    pub fn q(&self, i: usize) -> &Affine {
        &self.q[i]
    }

    /// The lower bound of solver constraint `j` (`j < m`: row `j`, else the
    /// bound on `z_{j-m}`); `None` is `-inf`.
    pub fn lower(&self, j: usize) -> Option<&Affine> {
        self.lower[j].as_ref()
    }

    /// The upper bound of solver constraint `j`; `None` is `+inf`.
    pub fn upper(&self, j: usize) -> Option<&Affine> {
        self.upper[j].as_ref()
    }

    /// The mpQP rows behind solver constraint `j`.
    pub fn source(&self, j: usize) -> RowSource {
        self.sources[j]
    }

    /// The solver constraint and side of mpQP row `r` (`r < problem.m()`;
    /// a dropped duplicate row gives its original's).
    pub fn constraint_of_row(&self, r: usize) -> (usize, Side) {
        self.of_row[r]
    }

    /// Constraint `j`'s coefficient vector in `z` (`n` entries): row `j` of
    /// `G` or the unit vector `e_{j-m}`.
    pub fn constraint_row(&self, j: usize) -> Vec<f64> {
        if j < self.m {
            self.g[j * self.n..(j + 1) * self.n].to_vec()
        } else {
            (0..self.n)
                .map(|i| f64::from(u8::from(i == j - self.m)))
                .collect()
        }
    }

    /// Buffers of the right sizes (zeros).
    pub fn buffers<S: QpScalar>(&self) -> QpBuffers<S> {
        QpBuffers {
            q: vec![S::ZERO; self.n],
            l: vec![S::ZERO; self.m],
            u: vec![S::ZERO; self.m],
            lb: vec![S::ZERO; self.n],
            ub: vec![S::ZERO; self.n],
        }
    }

    /// Fills `buf` with the solver inputs at `theta` (`p` entries), each
    /// evaluated in f64 and rounded to `S`; missing bounds are infinite.
    /// Allocates only if `buf` does not have the sizes of
    /// [`Self::buffers`].
    pub fn fill<S: QpScalar>(
        &self,
        theta: &[f64],
        buf: &mut QpBuffers<S>,
    ) -> Result<(), ParametricError> {
        if theta.len() != self.p {
            return Err(ParametricError::Dimension {
                expected: self.p,
                found: theta.len(),
            });
        }
        buf.q.resize(self.n, S::ZERO);
        buf.l.resize(self.m, S::ZERO);
        buf.u.resize(self.m, S::ZERO);
        buf.lb.resize(self.n, S::ZERO);
        buf.ub.resize(self.n, S::ZERO);
        let val = |a: Option<&Affine>, inf: f64| S::from_f64(a.map_or(inf, |a| a.eval(theta)));
        for (qi, a) in buf.q.iter_mut().zip(&self.q) {
            *qi = S::from_f64(a.eval(theta));
        }
        let (m, ninf) = (self.m, f64::NEG_INFINITY);
        for j in 0..m {
            buf.l[j] = val(self.lower(j), ninf);
            buf.u[j] = val(self.upper(j), f64::INFINITY);
        }
        for i in 0..self.n {
            buf.lb[i] = val(self.lower(m + i), ninf);
            buf.ub[i] = val(self.upper(m + i), f64::INFINITY);
        }
        Ok(())
    }

    /// The workspace lengths ([`scalar_len`], [`index_len`]) of the
    /// solver for this problem.
    pub fn workspace_len(&self) -> (usize, usize) {
        (scalar_len(self.n, self.m), index_len(self.n, self.m))
    }

    /// Sets up a solver for this problem's `H` and `G` (rounded to `S`) on
    /// the given workspaces (at least [`Self::workspace_len`] long).
    pub fn solver<'w, S: QpScalar>(
        &self,
        settings: QpSettings,
        scalars: &'w mut [S],
        indices: &'w mut [usize],
    ) -> Result<QpSolver<'w, S>, QpError> {
        let h: Vec<S> = self.h.iter().map(|&v| S::from_f64(v)).collect();
        let g: Vec<S> = self.g.iter().map(|&v| S::from_f64(v)).collect();
        QpSolver::new(self.n, self.m, &h, &g, settings, scalars, indices)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Start;

    #[test]
    fn bounds_mirrors_and_general_rows() {
        // z0 <= 1 + t, -z0 <= 2, z0 + z1 <= 3, -z0 - z1 <= 4 - t, 2 z1 <= 6,
        // z0 - z1 <= 5, a second upper bound on z0: 3 z0 <= 9, a repeat of
        // the first row.
        let p = MpqpProblem::from_json_str(
            r#"{"format": "kestrel.mpqp.v1", "H": [[2, 0], [0, 2]], "F": [[1, -1]],
            "G": [[1, 0], [-1, 0], [1, 1], [-1, -1], [0, 2], [1, -1], [3, 0], [1, 0]],
            "W": [1, 2, 3, 4, 6, 5, 9, 1], "E": [[1], [0], [0], [-1], [0], [0], [0], [1]],
            "theta_lb": [-1], "theta_ub": [1]}"#,
        )
        .unwrap();
        let qp = ParametricQp::from_mpqp(&p).unwrap();
        assert_eq!((qp.n(), qp.m(), qp.p()), (2, 3, 1));
        assert_eq!(qp.g(), &[1.0, 1.0, 1.0, -1.0, 3.0, 0.0]);
        assert_eq!(qp.constraint_of_row(0), (3, Side::Upper));
        assert_eq!(qp.constraint_of_row(1), (3, Side::Lower));
        assert_eq!(qp.constraint_of_row(3), (0, Side::Lower));
        assert_eq!(qp.constraint_of_row(4), (4, Side::Upper));
        assert_eq!(qp.constraint_of_row(6), (2, Side::Upper));
        assert_eq!(qp.constraint_of_row(7), (3, Side::Upper));
        assert_eq!(
            qp.source(0),
            RowSource {
                lower: Some(3),
                upper: Some(2)
            }
        );
        let mut buf = qp.buffers::<f64>();
        qp.fill(&[0.5], &mut buf).unwrap();
        assert_eq!(buf.q, vec![0.5, -0.5]);
        assert_eq!(buf.u, vec![3.0, 5.0, 9.0]);
        assert_eq!(buf.l, vec![-3.5, f64::NEG_INFINITY, f64::NEG_INFINITY]);
        assert_eq!(buf.lb, vec![-2.0, f64::NEG_INFINITY]);
        assert_eq!(buf.ub, vec![1.5, 3.0]);
        assert!(qp.fill(&[0.5, 1.0], &mut buf).is_err());
        let (ns, ni) = qp.workspace_len();
        let (mut s, mut ix) = (vec![0.0; ns], vec![0; ni]);
        let mut solver = qp.solver(QpSettings::default(), &mut s, &mut ix).unwrap();
        solver.solve(&buf.data(), Start::Cold).unwrap();
        let mut z = [0.0; 2];
        solver.solution(&mut z).unwrap();
        // Unconstrained optimum (-0.25, 0.25) is feasible.
        assert!((z[0] + 0.25).abs() < 1e-12 && (z[1] - 0.25).abs() < 1e-12);
    }

    #[test]
    fn zero_row_is_refused() {
        let p = MpqpProblem::from_json_str(
            r#"{"format": "kestrel.mpqp.v1", "H": [[2]], "F": [[1]],
            "G": [[0]], "W": [1], "E": [[0]], "theta_lb": [-1], "theta_ub": [1]}"#,
        )
        .unwrap();
        assert!(matches!(
            ParametricQp::from_mpqp(&p),
            Err(ParametricError::ZeroRow(0))
        ));
    }
}
