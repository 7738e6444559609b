//! The time-varying Kalman filter (thesis (5.10)-(5.12), corrected time
//! update, Joseph-form covariance update; feature `std`).

use crate::KalmanError;
use crate::dare::{check_shape, symmetrize};
use crate::design::KalmanDesign;
use kestrel_core::{Error, StateEstimator, check_len};
use nalgebra::{DMatrix, DVector};

/// A time-varying Kalman filter in `f64` (design-time, simulation and
/// reference use). The model matrices are public fields, so a time-varying
/// model (`A_k`, `B_k`, `C_k`, ...) is stepped by assigning them between samples.
///
/// ```text
/// measurement update  S = C P C' + R,  K = P C' S^-1                    (5.11)
///                     x = x + K (y - y0 - b - C x - D du_prev)          (5.12a)
///                     P = (I - K C) P (I - K C)' + K R K'     (Joseph form of 5.12b)
/// time update         x = A x + B du,  P = A P A' + G Q G'  (5.12c-d, from x_{k|k}, P_{k|k})
/// ```
///
/// The printed (5.12c) propagates `x_{k|k-1}`; the corrected time update
/// (errata) propagates the filtered estimate. The Joseph form keeps `P`
/// symmetric positive semidefinite in floating point for any gain.
///
/// ```
/// use kestrel_core::StateEstimator;
/// use kestrel_kalman::{TimeVaryingFilter, dlqe};
/// use nalgebra::{DMatrix, dmatrix};
/// let (a, c) = (dmatrix![1.0, 0.1; 0.0, 1.0], dmatrix![1.0, 0.0]);
/// let q = DMatrix::identity(2, 2) * 1e-3;
/// let mut f = TimeVaryingFilter::new(a.clone(), DMatrix::zeros(2, 1), c.clone(),
///     q.clone(), dmatrix![0.1], DMatrix::identity(2, 2)).unwrap();
/// for _ in 0..500 {
///     f.measurement_update(&[0.0]).unwrap();
///     f.time_update(&[0.0]).unwrap();
/// }
/// // The covariance converges to the stationary dlqe P.
/// let s = dlqe(&a, &DMatrix::identity(2, 2), &c, &q, &dmatrix![0.1], None).unwrap();
/// assert!((&f.p - &s.p).norm() < 1e-9 * s.p.norm());
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct TimeVaryingFilter {
    /// State matrix `A_k`.
    pub a: DMatrix<f64>,
    /// Input matrix `B_k` (acts on `u - u0`).
    pub b: DMatrix<f64>,
    /// Output matrix `C_k`.
    pub c: DMatrix<f64>,
    /// Feed-through `D_k` (acts on the input of the previous time update).
    pub d: DMatrix<f64>,
    /// Process noise covariance in state coordinates, `G Q G'`.
    pub q: DMatrix<f64>,
    /// Measurement noise covariance `R_k`.
    pub r: DMatrix<f64>,
    /// Input operating point.
    pub u0: DVector<f64>,
    /// Measurement offset: output operating point plus sensor bias.
    pub y_offset: DVector<f64>,
    /// The estimate (filtered after a measurement update, predicted after a time update).
    pub x: DVector<f64>,
    /// Its error covariance.
    pub p: DMatrix<f64>,
    /// The gain of the last measurement update.
    pub gain: DMatrix<f64>,
    du_last: DVector<f64>,
    rejected: u32,
}

impl TimeVaryingFilter {
    /// A filter for `x+ = A x + B u + w`, `y = C x + v`, `Cov(w) = Q`
    /// (state coordinates), `Cov(v) = R`, with `x_{1|0} = 0`, `P_{1|0} = p0`.
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        q: DMatrix<f64>,
        r: DMatrix<f64>,
        p0: DMatrix<f64>,
    ) -> Result<Self, KalmanError> {
        let (nx, nu, ny) = (a.nrows(), b.ncols(), c.nrows());
        check_shape("A", &a, nx, nx)?;
        check_shape("B", &b, nx, nu)?;
        check_shape("C", &c, ny, nx)?;
        check_shape("Q", &q, nx, nx)?;
        check_shape("R", &r, ny, ny)?;
        check_shape("P0", &p0, nx, nx)?;
        if r.clone().cholesky().is_none() {
            return Err(KalmanError::NotPositiveDefinite { name: "R" });
        }
        Ok(TimeVaryingFilter {
            a,
            b,
            c,
            d: DMatrix::zeros(ny, nu),
            q,
            r,
            u0: DVector::zeros(nu),
            y_offset: DVector::zeros(ny),
            x: DVector::zeros(nx),
            p: p0,
            gain: DMatrix::zeros(nx, ny),
            du_last: DVector::zeros(nu),
            rejected: 0,
        })
    }

    /// The time-varying filter of a stationary design (same model, noise,
    /// operating point and bias), started at `x = 0` with covariance `p0`.
    /// Designs with a cross-covariance `N` are refused (this filter assumes
    /// uncorrelated process and measurement noise).
    pub fn from_design(design: &KalmanDesign, p0: DMatrix<f64>) -> Result<Self, KalmanError> {
        if design.cross.is_some() {
            return Err(KalmanError::InvalidArgument {
                name: "N",
                reason:
                    "the time-varying filter assumes uncorrelated process and measurement noise"
                        .into(),
            });
        }
        let mut f = Self::new(
            design.a.clone(),
            design.b.clone(),
            design.c.clone(),
            &design.g * &design.q * design.g.transpose(),
            design.r.clone(),
            p0,
        )?;
        f.d = design.d.clone();
        f.u0 = design.u0.clone();
        f.y_offset = &design.y0 + &design.bias;
        Ok(f)
    }

    /// Rejected measurement updates so far.
    pub fn rejected(&self) -> u32 {
        self.rejected
    }
}

impl StateEstimator for TimeVaryingFilter {
    type Scalar = f64;
    fn nx(&self) -> usize {
        self.a.nrows()
    }
    fn nu(&self) -> usize {
        self.b.ncols()
    }
    fn ny(&self) -> usize {
        self.c.nrows()
    }
    fn measurement_update(&mut self, y: &[f64]) -> Result<(), Error> {
        let (nx, ny) = (self.a.nrows(), self.c.nrows());
        check_len(y, ny)?;
        if y.iter().any(|v| !v.is_finite()) {
            self.rejected = self.rejected.saturating_add(1);
            return Err(Error::NonFinite);
        }
        let mut s = &self.c * &self.p * self.c.transpose() + &self.r;
        symmetrize(&mut s);
        let pct = &self.p * self.c.transpose();
        let Some(chol) = s.cholesky() else {
            return Err(Error::NotPositiveDefinite);
        };
        let k = chol.solve(&pct.transpose()).transpose();
        let e = DVector::from_column_slice(y)
            - &self.y_offset
            - &self.c * &self.x
            - &self.d * &self.du_last;
        let x = &self.x + &k * e;
        let ikc = DMatrix::identity(nx, nx) - &k * &self.c;
        let mut p = &ikc * &self.p * ikc.transpose() + &k * &self.r * k.transpose();
        symmetrize(&mut p);
        if x.iter().chain(p.iter()).any(|v| !v.is_finite()) {
            self.rejected = self.rejected.saturating_add(1);
            return Err(Error::NonFinite);
        }
        self.x = x;
        self.p = p;
        self.gain = k;
        Ok(())
    }
    fn time_update(&mut self, u: &[f64]) -> Result<(), Error> {
        check_len(u, self.b.ncols())?;
        if u.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite);
        }
        let du = DVector::from_column_slice(u) - &self.u0;
        let x = &self.a * &self.x + &self.b * &du;
        let mut p = &self.a * &self.p * self.a.transpose() + &self.q;
        symmetrize(&mut p);
        if x.iter().chain(p.iter()).any(|v| !v.is_finite()) {
            return Err(Error::NonFinite);
        }
        self.x = x;
        self.p = p;
        self.du_last = du;
        Ok(())
    }
    fn estimate(&self) -> &[f64] {
        self.x.as_slice()
    }
    fn reset(&mut self, x0: &[f64]) -> Result<(), Error> {
        check_len(x0, self.a.nrows())?;
        if x0.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite);
        }
        self.x = DVector::from_column_slice(x0);
        self.du_last.fill(0.0);
        Ok(())
    }
}
