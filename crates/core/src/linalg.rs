//! Design-time linear algebra helpers (feature `std`): conversions to and
//! from nalgebra, and zero-order-hold discretisation ([`c2d`]).

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

use crate::error::Error;
use crate::matrix::Matrix;
use crate::scalar::Scalar;
use nalgebra::{DMatrix, SMatrix};

impl<S: Scalar, const R: usize, const C: usize> Matrix<S, R, C> {
    /// Converts to a statically sized nalgebra matrix of `f64`.
    pub fn to_nalgebra(&self) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|i, j| self.data[i][j].to_f64())
    }
    /// Converts from a statically sized nalgebra matrix of `f64`.
    pub fn from_nalgebra(m: &SMatrix<f64, R, C>) -> Self {
        Matrix::from_fn(|i, j| S::from_f64(m[(i, j)]))
    }
    /// Converts to a dynamically sized nalgebra matrix of `f64`.
    pub fn to_dmatrix(&self) -> DMatrix<f64> {
        DMatrix::from_fn(R, C, |i, j| self.data[i][j].to_f64())
    }
    /// Converts from a dynamically sized nalgebra matrix, checking its shape
    /// (rows first, then columns).
    pub fn try_from_dmatrix(m: &DMatrix<f64>) -> Result<Self, Error> {
        if m.nrows() != R {
            return Err(Error::DimensionMismatch {
                expected: R,
                found: m.nrows(),
            });
        }
        if m.ncols() != C {
            return Err(Error::DimensionMismatch {
                expected: C,
                found: m.ncols(),
            });
        }
        Ok(Matrix::from_fn(|i, j| S::from_f64(m[(i, j)])))
    }
}

/// The result of [`c2d`]: the zero-order-hold equivalents of `A` and `B`.
#[derive(Clone, Debug, PartialEq)]
pub struct Discretized {
    /// `Ad = exp(A ts)`.
    pub a: DMatrix<f64>,
    /// `Bd = integral_0^ts exp(A s) ds B`.
    pub b: DMatrix<f64>,
}

/// Zero-order-hold discretisation of `x' = A x + B u` with sample time `ts`.
///
/// Uses Van Loan's block method: `exp([[A, B], [0, 0]] ts) = [[Ad, Bd], [0, I]]`,
/// with nalgebra's scaling-and-squaring Padé matrix exponential. This is
/// exact for singular `A` (integrators), where `A^-1 (Ad - I) B` is not.
///
/// ```
/// use kestrel_core::c2d;
/// use nalgebra::dmatrix;
/// // Double integrator: Ad = [[1, T], [0, 1]], Bd = [T^2/2, T].
/// let d = c2d(&dmatrix![0.0, 1.0; 0.0, 0.0], &dmatrix![0.0; 1.0], 0.1).unwrap();
/// assert!((d.a[(0, 1)] - 0.1).abs() < 1e-15);
/// assert!((d.b[(0, 0)] - 0.005).abs() < 1e-15);
/// ```
pub fn c2d(a: &DMatrix<f64>, b: &DMatrix<f64>, ts: f64) -> Result<Discretized, Error> {
    let n = a.nrows();
    if a.ncols() != n {
        return Err(Error::DimensionMismatch {
            expected: n,
            found: a.ncols(),
        });
    }
    if b.nrows() != n {
        return Err(Error::DimensionMismatch {
            expected: n,
            found: b.nrows(),
        });
    }
    if !(ts.is_finite() && ts > 0.0) {
        return Err(Error::InvalidArgument(
            "sample time must be finite and positive",
        ));
    }
    if a.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(Error::NonFinite);
    }
    let m = b.ncols();
    let mut block = DMatrix::<f64>::zeros(n + m, n + m);
    block.view_mut((0, 0), (n, n)).copy_from(&(a * ts));
    block.view_mut((0, n), (n, m)).copy_from(&(b * ts));
    let e = block.exp();
    if e.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite);
    }
    Ok(Discretized {
        a: e.view((0, 0), (n, n)).into_owned(),
        b: e.view((0, n), (n, m)).into_owned(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{dmatrix, matrix};
    use proptest::prelude::*;

    #[test]
    fn double_integrator_closed_form() {
        for &t in &[0.001, 0.02, 0.5, 3.0] {
            let d = c2d(&dmatrix![0.0, 1.0; 0.0, 0.0], &dmatrix![0.0; 1.0], t).unwrap();
            assert_relative_eq!(d.a, dmatrix![1.0, t; 0.0, 1.0], epsilon = 1e-14);
            assert_relative_eq!(d.b, dmatrix![t * t / 2.0; t], epsilon = 1e-14);
        }
    }

    #[test]
    fn first_order_lag_closed_form() {
        // x' = -x/tau + k/tau u  =>  Ad = e^{-T/tau}, Bd = k (1 - e^{-T/tau}).
        let (tau, k, t) = (0.05, 3.0, 0.02);
        let d = c2d(&dmatrix![-1.0 / tau], &dmatrix![k / tau], t).unwrap();
        let e = (-t / tau).exp();
        assert_relative_eq!(d.a[(0, 0)], e, max_relative = 1e-14);
        assert_relative_eq!(d.b[(0, 0)], k * (1.0 - e), max_relative = 1e-14);
    }

    #[test]
    fn undamped_oscillator_closed_form() {
        // x' = [[0, w], [-w, 0]] x + [0; 1] u.
        let (w, t) = (7.0_f64, 0.02);
        let d = c2d(&dmatrix![0.0, w; -w, 0.0], &dmatrix![0.0; 1.0], t).unwrap();
        let (s, c) = (w * t).sin_cos();
        assert_relative_eq!(d.a, dmatrix![c, s; -s, c], epsilon = 1e-14);
        assert_relative_eq!(d.b, dmatrix![(1.0 - c) / w; s / w], epsilon = 1e-14);
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = dmatrix![0.0, 1.0; 0.0, 0.0];
        let b = dmatrix![0.0; 1.0];
        assert!(matches!(
            c2d(&dmatrix![0.0, 1.0], &b, 0.1),
            Err(Error::DimensionMismatch { .. })
        ));
        assert!(matches!(
            c2d(&a, &dmatrix![1.0], 0.1),
            Err(Error::DimensionMismatch { .. })
        ));
        assert!(matches!(c2d(&a, &b, 0.0), Err(Error::InvalidArgument(_))));
        assert!(matches!(
            c2d(&a, &b, f64::NAN),
            Err(Error::InvalidArgument(_))
        ));
        assert!(matches!(
            c2d(&dmatrix![f64::NAN, 0.0; 0.0, 0.0], &b, 0.1),
            Err(Error::NonFinite)
        ));
    }

    #[test]
    fn nalgebra_round_trip() {
        let m = Matrix::<f32, 2, 3>::from_rows([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        let s = m.to_nalgebra();
        assert_eq!(s, matrix![1.0, 2.0, 3.0; 4.0, 5.0, 6.0]);
        assert_eq!(Matrix::<f32, 2, 3>::from_nalgebra(&s), m);
        let d = m.to_dmatrix();
        assert_eq!(Matrix::<f32, 2, 3>::try_from_dmatrix(&d).unwrap(), m);
        assert!(Matrix::<f32, 3, 2>::try_from_dmatrix(&d).is_err());
        assert!(Matrix::<f32, 2, 2>::try_from_dmatrix(&d).is_err());
    }

    proptest! {
        /// Two steps of ts equal one step of 2 ts (semigroup law), and
        /// Bd satisfies A Bd = (Ad - I) B (exact identity of the ZOH integral).
        #[test]
        fn zoh_laws(v in proptest::collection::vec(-2.0f64..2.0, 9), bv in proptest::collection::vec(-2.0f64..2.0, 6), t in 0.001f64..0.2) {
            let a = DMatrix::from_row_slice(3, 3, &v);
            let b = DMatrix::from_row_slice(3, 2, &bv);
            let d1 = c2d(&a, &b, t).unwrap();
            let d2 = c2d(&a, &b, 2.0 * t).unwrap();
            prop_assert!((&d1.a * &d1.a - &d2.a).amax() < 1e-11);
            prop_assert!((&d1.a * &d1.b + &d1.b - &d2.b).amax() < 1e-11);
            let lhs = &a * &d1.b;
            let rhs = (&d1.a - DMatrix::identity(3, 3)) * &b;
            prop_assert!((lhs - rhs).amax() < 1e-11);
        }
    }
}
