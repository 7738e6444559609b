//! `dlqr` and `dlqe` with python-control's (and MATLAB's) meanings (feature `std`).

use crate::KalmanError;
use crate::dare::{DareSettings, check_shape, dare_with, symmetrize, symmetrized};
use nalgebra::{Complex, DMatrix, DVector};

/// The discrete linear-quadratic regulator from [`dlqr`].
#[derive(Clone, Debug, PartialEq)]
pub struct Lqr {
    /// State feedback gain `K` (`m x n`): `u = -K x` minimises
    /// `sum x'Qx + u'Ru + 2 x'Nu` (python-control's `K`).
    pub k: DMatrix<f64>,
    /// The Riccati solution `S` (python-control's `S`): the cost-to-go is
    /// `x'Sx`, the LQ terminal weight of the MPC (thesis (7.18), corrected).
    pub s: DMatrix<f64>,
    /// Eigenvalues of `A - B K` (python-control's `E`).
    pub closed_loop_eigenvalues: DVector<Complex<f64>>,
    /// Relative residual of the Riccati equation (see [`crate::DareSolution::residual`]).
    pub residual: f64,
}

/// Discrete LQR: python-control's `dlqr(A, B, Q, R[, N])`.
///
/// ```
/// use kestrel_kalman::dlqr;
/// use nalgebra::dmatrix;
/// // Double integrator, sampled at 0.1 s.
/// let a = dmatrix![1.0, 0.1; 0.0, 1.0];
/// let b = dmatrix![0.005; 0.1];
/// let lqr = dlqr(&a, &b, &dmatrix![1.0, 0.0; 0.0, 0.0], &dmatrix![0.1], None).unwrap();
/// assert!(lqr.closed_loop_eigenvalues.iter().all(|z| z.norm() < 1.0));
/// assert_eq!(lqr.k.shape(), (1, 2));
/// ```
pub fn dlqr(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    n: Option<&DMatrix<f64>>,
) -> Result<Lqr, KalmanError> {
    dlqr_with(a, b, q, r, n, &DareSettings::default())
}

/// [`dlqr`] with explicit Riccati settings.
pub fn dlqr_with(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    n: Option<&DMatrix<f64>>,
    settings: &DareSettings,
) -> Result<Lqr, KalmanError> {
    let sol = dare_with(a, b, q, r, n, settings)?;
    Ok(Lqr {
        k: sol.gain,
        s: sol.x,
        closed_loop_eigenvalues: sol.closed_loop_eigenvalues,
        residual: sol.residual,
    })
}

/// The stationary Kalman filter from [`dlqe`].
///
/// For `x+ = A x + B u + G w`, `y = C x + D u + v`, `Cov(w) = QN`,
/// `Cov(v) = RN`, `E[w v'] = NN`:
///
/// - measurement update `x_{k|k} = x_{k|k-1} + M (y_k - C x_{k|k-1} - D u_k)`;
/// - time update (corrected (5.15b), errata) `x_{k+1|k} = A x_{k|k} + B u_k + (L - A M) e_k`,
///   i.e. the predictor `x_{k+1|k} = A x_{k|k-1} + B u_k + L e_k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Dlqe {
    /// Measurement-update (innovation) gain `M = P C' (C P C' + RN)^-1`, `n x p` (MATLAB's `M`).
    pub m: DMatrix<f64>,
    /// Predictor gain `L = (A P C' + G NN)(C P C' + RN)^-1`, `n x p`; `L = A M`
    /// without cross-covariance (python-control's `L`).
    pub l: DMatrix<f64>,
    /// Steady-state covariance of the one-step prediction error `x_k - x_{k|k-1}` (MATLAB's and python-control's `P`).
    pub p: DMatrix<f64>,
    /// Steady-state covariance after the measurement update, `Z = P - M (C P C' + RN) M'` (MATLAB's `Z`).
    pub z: DMatrix<f64>,
    /// Innovation covariance `C P C' + RN`.
    pub innovation_covariance: DMatrix<f64>,
    /// Eigenvalues of the predictor `A - L C` (python-control's `E`).
    pub closed_loop_eigenvalues: DVector<Complex<f64>>,
    /// Relative residual of the filter Riccati equation.
    pub residual: f64,
}

/// Stationary Kalman filter design: python-control's `dlqe(A, G, C, QN, RN[, NN])`
/// (thesis (5.15c)-(5.15d); MATLAB's `dlqe` without `NN`).
///
/// Solves the dual DARE `P = A P A' - (A P C' + G NN)(C P C' + RN)^-1 (...)' + G QN G'`.
/// An unobservable unstable mode is reported as [`KalmanError::NotDetectable`],
/// an unstable mode the process noise does not excite as [`KalmanError::NotStabilizable`].
///
/// ```
/// use kestrel_kalman::dlqe;
/// use nalgebra::dmatrix;
/// let a = dmatrix![1.0, 0.02; 0.0, 1.0];
/// let c = dmatrix![1.0, 0.0];
/// let g = nalgebra::DMatrix::identity(2, 2);
/// let f = dlqe(&a, &g, &c, &dmatrix![1e-4, 0.0; 0.0, 1e-2], &dmatrix![1e-2], None).unwrap();
/// // Without cross-covariance the predictor gain is A M.
/// assert!((&f.l - &a * &f.m).norm() < 1e-12);
/// ```
pub fn dlqe(
    a: &DMatrix<f64>,
    g: &DMatrix<f64>,
    c: &DMatrix<f64>,
    qn: &DMatrix<f64>,
    rn: &DMatrix<f64>,
    nn: Option<&DMatrix<f64>>,
) -> Result<Dlqe, KalmanError> {
    dlqe_with(a, g, c, qn, rn, nn, &DareSettings::default())
}

/// [`dlqe`] with explicit Riccati settings.
pub fn dlqe_with(
    a: &DMatrix<f64>,
    g: &DMatrix<f64>,
    c: &DMatrix<f64>,
    qn: &DMatrix<f64>,
    rn: &DMatrix<f64>,
    nn: Option<&DMatrix<f64>>,
    settings: &DareSettings,
) -> Result<Dlqe, KalmanError> {
    let n = a.nrows();
    let p_out = c.nrows();
    check_shape("A", a, n, n)?;
    check_shape("C", c, p_out, n)?;
    if g.nrows() != n {
        return Err(KalmanError::DimensionMismatch {
            name: "G",
            expected_rows: n,
            expected_cols: g.ncols(),
            found_rows: g.nrows(),
            found_cols: g.ncols(),
        });
    }
    let w = g.ncols();
    check_shape("G", g, n, w)?;
    check_shape("QN", qn, w, w)?;
    check_shape("RN", rn, p_out, p_out)?;
    if let Some(nn) = nn {
        check_shape("NN", nn, w, p_out)?;
    }
    let qn = symmetrized("QN", qn, settings.symmetry_tolerance)?;
    let mut gqg = g * qn * g.transpose();
    symmetrize(&mut gqg);
    let gn = nn.map(|nn| g * nn);
    let sol = dare_with(
        &a.transpose(),
        &c.transpose(),
        &gqg,
        rn,
        gn.as_ref(),
        settings,
    )
    .map_err(|e| match e {
        KalmanError::NotStabilizable { eigenvalue } => KalmanError::NotDetectable { eigenvalue },
        KalmanError::NotDetectable { eigenvalue } => KalmanError::NotStabilizable { eigenvalue },
        other => other,
    })?;
    let p = sol.x;
    let l = sol.gain.transpose();
    let mut s = c * &p * c.transpose() + rn;
    symmetrize(&mut s);
    let pct = &p * c.transpose();
    // M = P C' S^-1, via S M' = C P.
    let m = match s.clone().cholesky() {
        Some(ch) => ch.solve(&pct.transpose()).transpose(),
        None => {
            return Err(KalmanError::NotPositiveDefinite {
                name: "C P C' + RN",
            });
        }
    };
    let mut z = &p - &m * &s * m.transpose();
    symmetrize(&mut z);
    Ok(Dlqe {
        m,
        l,
        p,
        z,
        innovation_covariance: s,
        closed_loop_eigenvalues: sol.closed_loop_eigenvalues,
        residual: sol.residual,
    })
}
