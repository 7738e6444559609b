//! Diagonal preconditioning of the Hessian.
//!
//! With `z = D v` (`D` diagonal, positive) the box stays a box, so the
//! projection stays a clamp, while the Hessian becomes `D H D`. The fast
//! gradient method's rate depends on its condition number `L / mu`.

use crate::FgmError;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// How to choose the diagonal scaling `D`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Preconditioner {
    /// `D = I`.
    None,
    /// `D = diag(H)^-1/2`: unit diagonal.
    Jacobi,
    /// The diagonal `D` that minimises the condition number of `D H D`,
    /// from a semidefinite program solved with clarabel (as FiOrdOs's
    /// auto-preconditioning). Falls back to the better of Jacobi and the
    /// SDP result if numerical trouble makes the SDP scaling worse.
    #[default]
    OptimalDiagonal,
}

impl Preconditioner {
    /// The name used in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preconditioner::None => "none",
            Preconditioner::Jacobi => "jacobi",
            Preconditioner::OptimalDiagonal => "optimal-diagonal",
        }
    }
}

/// The extreme eigenvalues of a Hessian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spectrum {
    /// Largest eigenvalue: the Lipschitz constant `L` of the gradient.
    pub l: f64,
    /// Smallest eigenvalue: the strong convexity `mu` (0 if singular).
    pub mu: f64,
}

impl Spectrum {
    /// `L / mu` (infinite when `mu = 0`).
    pub fn condition(&self) -> f64 {
        if self.mu > 0.0 {
            self.l / self.mu
        } else {
            f64::INFINITY
        }
    }
}

/// Eigenvalues of a symmetric matrix; a tiny negative `mu` from rounding
/// (relative 1e-12) counts as 0, a clearly negative one is an error.
pub fn spectrum(h: &DMatrix<f64>) -> Result<Spectrum, FgmError> {
    if h.iter().any(|v| !v.is_finite()) {
        return Err(FgmError::NonFinite("H"));
    }
    let sym = (h + h.transpose()) * 0.5;
    let eig = SymmetricEigen::new(sym).eigenvalues;
    let l = eig.max();
    let mu = eig.min();
    if l <= 0.0 {
        return Err(FgmError::NotConvex { min_eigenvalue: mu });
    }
    if mu < -1e-12 * l {
        return Err(FgmError::NotConvex { min_eigenvalue: mu });
    }
    Ok(Spectrum { l, mu: mu.max(0.0) })
}

/// The result of preconditioning.
#[derive(Clone, Debug, PartialEq)]
pub struct Preconditioning {
    /// The method used.
    pub method: Preconditioner,
    /// The scaling `z = D v`, normalised to `max d = 1`.
    pub d: DVector<f64>,
    /// Spectrum of `H`.
    pub before: Spectrum,
    /// Spectrum of `D H D`.
    pub after: Spectrum,
}

/// `D H D`.
pub fn scale_hessian(h: &DMatrix<f64>, d: &DVector<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(h.nrows(), h.ncols(), |i, j| d[i] * h[(i, j)] * d[j])
}

/// Computes the diagonal scaling by `method`.
///
/// # Errors
/// [`FgmError::NotConvex`] for a Hessian with a negative eigenvalue or a
/// non-positive diagonal entry, [`FgmError::Solver`] if the SDP fails.
pub fn precondition(h: &DMatrix<f64>, method: Preconditioner) -> Result<Preconditioning, FgmError> {
    let before = spectrum(h)?;
    let n = h.nrows();
    let d = match method {
        Preconditioner::None => DVector::from_element(n, 1.0),
        Preconditioner::Jacobi => jacobi(h)?,
        Preconditioner::OptimalDiagonal => {
            let dj = jacobi(h)?;
            if before.mu <= 0.0 {
                // The SDP needs H^-1; with a singular H no scaling changes
                // mu = 0, and Jacobi is as good as anything.
                dj
            } else {
                let hj = scale_hessian(h, &dj);
                let e = optimal_diagonal_sdp(&hj)?;
                let dsdp = DVector::from_fn(n, |i, _| dj[i] * e[i].max(0.0).sqrt());
                let k_sdp = if dsdp.iter().all(|v| *v > 0.0 && v.is_finite()) {
                    spectrum(&scale_hessian(h, &dsdp))?.condition()
                } else {
                    f64::INFINITY
                };
                let k_jac = spectrum(&hj)?.condition();
                if k_sdp <= k_jac { dsdp } else { dj }
            }
        }
    };
    let dmax = d.max();
    let d = d / dmax;
    let after = spectrum(&scale_hessian(h, &d))?;
    Ok(Preconditioning {
        method,
        d,
        before,
        after,
    })
}

fn jacobi(h: &DMatrix<f64>) -> Result<DVector<f64>, FgmError> {
    let n = h.nrows();
    if let Some(i) = (0..n).find(|&i| h[(i, i)] <= 0.0) {
        return Err(FgmError::NotConvex {
            min_eigenvalue: h[(i, i)].min(0.0),
        });
    }
    Ok(DVector::from_fn(n, |i, _| 1.0 / h[(i, i)].sqrt()))
}

/// Index of entry `(i, j)`, `i <= j`, in clarabel's scaled upper-triangle,
/// column-major `svec`.
fn svec_index(i: usize, j: usize) -> usize {
    j * (j + 1) / 2 + i
}

/// The optimal diagonal preconditioner as one SDP.
///
/// With `E = D^2` diagonal: `D H D <= I` iff `E <= H^-1`, and
/// `D H D >= s^2 I` iff `[[H, s I], [s I, E]] >= 0` (Schur complement), both
/// linear in `(E, s)`. Maximising `s` minimises `cond(D H D) <= 1 / s^2`.
/// Returns `diag(E)`.
fn optimal_diagonal_sdp(h: &DMatrix<f64>) -> Result<DVector<f64>, FgmError> {
    let n = h.nrows();
    let hinv = h
        .clone()
        .cholesky()
        .ok_or(FgmError::NotConvex {
            min_eigenvalue: 0.0,
        })?
        .inverse();
    let sqrt2 = std::f64::consts::SQRT_2;
    let t1 = n * (n + 1) / 2;
    let t2 = 2 * n * (2 * n + 1) / 2;
    // Variables x = [e_0 .. e_{n-1}, s]; constraints A x + slack = b, slack in cones.
    let mut b = vec![0.0; t1 + t2];
    for j in 0..n {
        for i in 0..=j {
            let w = if i == j { 1.0 } else { sqrt2 };
            b[svec_index(i, j)] = w * hinv[(i, j)];
            b[t1 + svec_index(i, j)] = w * h[(i, j)];
        }
    }
    // Columns of A (CSC): e_k enters both cones at a diagonal position, s
    // enters the second at the off-diagonal identity positions (k, n + k).
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for k in 0..n {
        rowval.push(svec_index(k, k));
        nzval.push(1.0); // slack = H^-1 - E
        rowval.push(t1 + svec_index(n + k, n + k));
        nzval.push(-1.0); // slack = [..] + E in the lower-right block
        colptr.push(rowval.len());
    }
    let mut srows: Vec<usize> = (0..n).map(|k| t1 + svec_index(k, n + k)).collect();
    srows.sort_unstable();
    for r in srows {
        rowval.push(r);
        nzval.push(-sqrt2);
    }
    colptr.push(rowval.len());
    let a = CscMatrix::new(t1 + t2, n + 1, colptr, rowval, nzval);
    let p = CscMatrix::<f64>::zeros((n + 1, n + 1));
    let mut q = vec![0.0; n + 1];
    q[n] = -1.0;
    let cones = [
        SupportedConeT::PSDTriangleConeT(n),
        SupportedConeT::PSDTriangleConeT(2 * n),
    ];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .build()
        .map_err(|e| FgmError::Solver(format!("{e:?}")))?;
    let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings)
        .map_err(|e| FgmError::Solver(format!("{e:?}")))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {
            Ok(DVector::from_column_slice(&solver.solution.x[..n]))
        }
        other => Err(FgmError::Solver(format!(
            "optimal diagonal preconditioner SDP: {other:?}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over a grid of scalings of a 2 x 2 matrix.
    #[test]
    fn optimal_diagonal_matches_grid_search_2x2() {
        let h = DMatrix::from_row_slice(2, 2, &[100.0, 9.0, 9.0, 1.0]);
        let pc = precondition(&h, Preconditioner::OptimalDiagonal).unwrap();
        let mut best = f64::INFINITY;
        for k in 0..20001 {
            let r = 10f64.powf(-3.0 + 6.0 * k as f64 / 20000.0);
            let d = DVector::from_vec(vec![1.0, r]);
            best = best.min(spectrum(&scale_hessian(&h, &d)).unwrap().condition());
        }
        assert!(
            pc.after.condition() <= best * (1.0 + 1e-4),
            "{} vs {best}",
            pc.after.condition()
        );
        assert!(pc.after.condition() >= best * (1.0 - 1e-3));
        let jac = precondition(&h, Preconditioner::Jacobi).unwrap();
        assert!(pc.after.condition() <= jac.after.condition() * (1.0 + 1e-9));
    }

    #[test]
    fn optimal_never_worse_than_jacobi_on_random_spd() {
        use rand::{RngExt, SeedableRng};
        // Uniform in [-1, 1) from the workspace's seeded generator.
        let mut rng = rand_xoshiro::SplitMix64::seed_from_u64(7);
        let mut rnd = || rng.random::<f64>() * 2.0 - 1.0;
        for n in [3, 6, 10] {
            let a = DMatrix::from_fn(n, n, |_, _| rnd());
            let s = DVector::from_fn(n, |_, _| 10f64.powf(2.0 * rnd()));
            let h = DMatrix::from_diagonal(&s)
                * (a.transpose() * &a + DMatrix::identity(n, n) * 0.1)
                * DMatrix::from_diagonal(&s);
            let h = (&h + h.transpose()) * 0.5;
            let o = precondition(&h, Preconditioner::OptimalDiagonal).unwrap();
            let j = precondition(&h, Preconditioner::Jacobi).unwrap();
            assert!(o.after.condition() <= j.after.condition() * (1.0 + 1e-9));
            assert!(j.after.condition() <= o.before.condition() * 10.0);
        }
    }

    #[test]
    fn non_convex_hessian_is_refused() {
        let h = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        let e = precondition(&h, Preconditioner::Jacobi).unwrap_err();
        assert!(matches!(e, FgmError::NotConvex { .. }));
        assert!(e.to_string().contains("not convex"));
        let neg = DMatrix::from_row_slice(1, 1, &[-1.0]);
        assert!(matches!(spectrum(&neg), Err(FgmError::NotConvex { .. })));
    }
}
