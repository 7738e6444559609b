//! The shared state-space traits: a discrete linear model, a state
//! estimator and a control law.
//!
//! The traits use slices and report their dimensions at run time, so one
//! trait serves both the const-generic run-time types (checked once, then
//! allocation-free) and the design-time types whose sizes come from a file.

use crate::error::{Error, check_len};
use crate::matrix::Matrix;
use crate::scalar::Scalar;

/// A discrete-time linear model `x+ = A x + B u`, `y = C x + D u`.
///
/// Entries are read one at a time so that any storage (const-generic arrays,
/// nalgebra matrices, tables in program memory) can implement it.
///
/// ```
/// use kestrel_core::{DiscreteLinearModel, Matrix, StateSpace};
/// // x+ = 0.5 x + u, y = 2 x
/// let m = StateSpace::new(
///     Matrix::from_rows([[0.5]]), Matrix::from_rows([[1.0]]),
///     Matrix::from_rows([[2.0]]), Matrix::from_rows([[0.0]]), 0.02);
/// let mut x_next = [0.0];
/// m.step_into(&[1.0], &[1.0], &mut x_next).unwrap();
/// assert_eq!(x_next, [1.5]);
/// assert_eq!((m.nx(), m.nu(), m.ny()), (1, 1, 1));
/// ```
pub trait DiscreteLinearModel {
    /// The scalar type of the entries.
    type Scalar: Scalar;
    /// Number of states.
    fn nx(&self) -> usize;
    /// Number of inputs.
    fn nu(&self) -> usize;
    /// Number of outputs.
    fn ny(&self) -> usize;
    /// Sample time in seconds (`0` marks a continuous-time model).
    fn sample_time(&self) -> f64;
    /// Entry `(i, j)` of `A` (`nx x nx`).
    fn a(&self, i: usize, j: usize) -> Self::Scalar;
    /// Entry `(i, j)` of `B` (`nx x nu`).
    fn b(&self, i: usize, j: usize) -> Self::Scalar;
    /// Entry `(i, j)` of `C` (`ny x nx`).
    fn c(&self, i: usize, j: usize) -> Self::Scalar;
    /// Entry `(i, j)` of `D` (`ny x nu`).
    fn d(&self, i: usize, j: usize) -> Self::Scalar;

    /// `x_next = A x + B u`, with the slice lengths checked.
    fn step_into(
        &self,
        x: &[Self::Scalar],
        u: &[Self::Scalar],
        x_next: &mut [Self::Scalar],
    ) -> Result<(), Error> {
        let (nx, nu) = (self.nx(), self.nu());
        check_len(x, nx)?;
        check_len(u, nu)?;
        check_len(x_next, nx)?;
        for (i, xn) in x_next.iter_mut().enumerate() {
            let mut acc = Self::Scalar::ZERO;
            for (j, xj) in x.iter().enumerate() {
                acc = acc.mul_add(self.a(i, j), *xj);
            }
            for (j, uj) in u.iter().enumerate() {
                acc = acc.mul_add(self.b(i, j), *uj);
            }
            *xn = acc;
        }
        Ok(())
    }

    /// `y = C x + D u`, with the slice lengths checked.
    fn output_into(
        &self,
        x: &[Self::Scalar],
        u: &[Self::Scalar],
        y: &mut [Self::Scalar],
    ) -> Result<(), Error> {
        check_len(x, self.nx())?;
        check_len(u, self.nu())?;
        check_len(y, self.ny())?;
        for (i, yi) in y.iter_mut().enumerate() {
            let mut acc = Self::Scalar::ZERO;
            for (j, xj) in x.iter().enumerate() {
                acc = acc.mul_add(self.c(i, j), *xj);
            }
            for (j, uj) in u.iter().enumerate() {
                acc = acc.mul_add(self.d(i, j), *uj);
            }
            *yi = acc;
        }
        Ok(())
    }
}

/// A state estimator run once per sample: first the measurement update with
/// `y_k`, then (after the controller has chosen `u_k`) the time update.
///
/// Implementations must not let a non-finite measurement into the estimate:
/// they return [`Error::NonFinite`] and keep the previous estimate.
pub trait StateEstimator {
    /// The scalar type.
    type Scalar: Scalar;
    /// Number of estimated states.
    fn nx(&self) -> usize;
    /// Number of inputs the time update takes.
    fn nu(&self) -> usize;
    /// Number of measured outputs.
    fn ny(&self) -> usize;
    /// Measurement update with the output `y_k` measured at this sample.
    fn measurement_update(&mut self, y: &[Self::Scalar]) -> Result<(), Error>;
    /// Time update with the input `u_k` applied at this sample.
    fn time_update(&mut self, u: &[Self::Scalar]) -> Result<(), Error>;
    /// The current estimate (filtered after a measurement update, predicted after a time update).
    fn estimate(&self) -> &[Self::Scalar];
    /// Resets the estimate to `x0`.
    fn reset(&mut self, x0: &[Self::Scalar]) -> Result<(), Error>;
}

/// A control law: state estimate and reference (plus any scheduling
/// parameters such as the throttle) in, input out.
pub trait ControlLaw {
    /// The scalar type.
    type Scalar: Scalar;
    /// Number of states the law reads.
    fn nx(&self) -> usize;
    /// Number of reference / parameter entries the law reads.
    fn nr(&self) -> usize;
    /// Number of inputs the law writes.
    fn nu(&self) -> usize;
    /// Computes the input `u` for state `x` and reference `r`.
    fn control(
        &mut self,
        x: &[Self::Scalar],
        r: &[Self::Scalar],
        u: &mut [Self::Scalar],
    ) -> Result<(), Error>;
}

/// A discrete state-space model with const-generic dimensions, held in arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateSpace<S, const NX: usize, const NU: usize, const NY: usize> {
    /// State matrix.
    pub a: Matrix<S, NX, NX>,
    /// Input matrix.
    pub b: Matrix<S, NX, NU>,
    /// Output matrix.
    pub c: Matrix<S, NY, NX>,
    /// Feed-through matrix.
    pub d: Matrix<S, NY, NU>,
    /// Sample time in seconds.
    pub ts: f64,
}

impl<S: Scalar, const NX: usize, const NU: usize, const NY: usize> StateSpace<S, NX, NU, NY> {
    /// A model from its matrices and sample time.
    pub const fn new(
        a: Matrix<S, NX, NX>,
        b: Matrix<S, NX, NU>,
        c: Matrix<S, NY, NX>,
        d: Matrix<S, NY, NU>,
        ts: f64,
    ) -> Self {
        StateSpace { a, b, c, d, ts }
    }
    /// `A x + B u`.
    #[inline]
    pub fn step(&self, x: &[S; NX], u: &[S; NU]) -> [S; NX] {
        let mut xn = self.a.mul_vec(x);
        self.b.mul_vec_acc(u, &mut xn);
        xn
    }
    /// `C x + D u`.
    #[inline]
    pub fn output(&self, x: &[S; NX], u: &[S; NU]) -> [S; NY] {
        let mut y = self.c.mul_vec(x);
        self.d.mul_vec_acc(u, &mut y);
        y
    }
    /// Copies any model of the same size into arrays, converting the scalar.
    pub fn from_model<M: DiscreteLinearModel>(m: &M) -> Result<Self, Error> {
        for (found, expected) in [(m.nx(), NX), (m.nu(), NU), (m.ny(), NY)] {
            if found != expected {
                return Err(Error::DimensionMismatch { expected, found });
            }
        }
        let conv = |v: M::Scalar| S::from_f64(v.to_f64());
        Ok(StateSpace {
            a: Matrix::from_fn(|i, j| conv(m.a(i, j))),
            b: Matrix::from_fn(|i, j| conv(m.b(i, j))),
            c: Matrix::from_fn(|i, j| conv(m.c(i, j))),
            d: Matrix::from_fn(|i, j| conv(m.d(i, j))),
            ts: m.sample_time(),
        })
    }
}

impl<S: Scalar, const NX: usize, const NU: usize, const NY: usize> DiscreteLinearModel
    for StateSpace<S, NX, NU, NY>
{
    type Scalar = S;
    fn nx(&self) -> usize {
        NX
    }
    fn nu(&self) -> usize {
        NU
    }
    fn ny(&self) -> usize {
        NY
    }
    fn sample_time(&self) -> f64 {
        self.ts
    }
    fn a(&self, i: usize, j: usize) -> S {
        self.a.get(i, j).unwrap_or(S::ZERO)
    }
    fn b(&self, i: usize, j: usize) -> S {
        self.b.get(i, j).unwrap_or(S::ZERO)
    }
    fn c(&self, i: usize, j: usize) -> S {
        self.c.get(i, j).unwrap_or(S::ZERO)
    }
    fn d(&self, i: usize, j: usize) -> S {
        self.d.get(i, j).unwrap_or(S::ZERO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scalar::Q16;

    fn model() -> StateSpace<f64, 2, 1, 1> {
        StateSpace::new(
            Matrix::from_rows([[1.0, 0.02], [0.0, 1.0]]),
            Matrix::from_rows([[0.0002], [0.02]]),
            Matrix::from_rows([[1.0, 0.0]]),
            Matrix::from_rows([[0.5]]),
            0.02,
        )
    }

    #[test]
    fn trait_step_matches_const_step() {
        let m = model();
        let x = [0.3, -1.2];
        let u = [2.0];
        let mut xn = [0.0; 2];
        m.step_into(&x, &u, &mut xn).unwrap();
        assert_eq!(xn, m.step(&x, &u));
        let mut y = [0.0];
        m.output_into(&x, &u, &mut y).unwrap();
        assert_eq!(y, m.output(&x, &u));
        assert!((y[0] - (0.3 + 1.0)).abs() < 1e-15);
    }

    #[test]
    fn wrong_lengths_are_errors() {
        let m = model();
        let mut xn = [0.0; 2];
        assert_eq!(
            m.step_into(&[0.0], &[0.0], &mut xn),
            Err(Error::DimensionMismatch {
                expected: 2,
                found: 1
            })
        );
        let mut y = [0.0; 2];
        assert!(m.output_into(&[0.0; 2], &[0.0], &mut y).is_err());
        assert!(StateSpace::<f64, 3, 1, 1>::from_model(&m).is_err());
    }

    #[test]
    fn converts_between_scalars() {
        let m = model();
        let q = StateSpace::<Q16, 2, 1, 1>::from_model(&m).unwrap();
        let x = [Q16::from_f64(0.5), Q16::from_f64(1.0)];
        let xn = q.step(&x, &[Q16::from_f64(1.0)]);
        let want = m.step(&[0.5, 1.0], &[1.0]);
        for k in 0..2 {
            assert!((xn[k].to_f64() - want[k]).abs() < 1e-4);
        }
        assert_eq!(q.sample_time(), 0.02);
    }
}
