//! The stationary Kalman filter's run-time step: `no_std`, allocation-free,
//! panic-free, generic over [`Scalar`] and const dimensions.
//!
//! With the deviation variables `du = u - u0` and `dy = y - y0 - b` (`u0`,
//! `y0`: the model's operating point, `b`: the known gyro bias, folded
//! offline into one offset), one sample is
//!
//! ```text
//! measurement update   e   = dy_k - C x_{k|k-1} - D du_{k-1}
//!                      x_{k|k} = x_{k|k-1} + M e                         (5.15a)
//! time update          x_{k+1|k} = A x_{k|k} + B du_k + (L - A M) e      (5.15b, corrected)
//! ```
//!
//! The printed (5.15b) propagates `x_{k|k-1}`; the errata (and any Kalman
//! filter text) propagate the filtered `x_{k|k}`, as here. `L - A M` is
//! zero unless the process and measurement noise are correlated; it is
//! skipped then. `D` (rare for the identified models) multiplies the
//! input held when `y_k` was sampled, `u_{k-1}` (the one passed to the
//! last time update), because `u_k` is computed from `x_{k|k}`.
//!
//! Multiply-adds per sample: `NY NX + NX NY` (measurement) plus
//! `NX NX + NX NU` (time), plus `NY NU` with `D` and `NX NY` with a cross
//! term. For the thesis's black-box model (5 states, 4 inputs, 3 outputs)
//! that is 15 + 15 + 25 + 20 = **75**; see [`StationaryGains::multiply_adds`].
//! No divisions, no square roots: every constant is computed offline.

use kestrel_core::{Error, Matrix, Scalar, StateEstimator, all_finite, check_len};

/// The constant tables of a stationary filter, folded offline (plain data,
/// can live in a `static`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StationaryGains<S, const NX: usize, const NU: usize, const NY: usize> {
    /// State matrix `A`.
    pub a: Matrix<S, NX, NX>,
    /// Input matrix `B` (acts on `u - u0`).
    pub b: Matrix<S, NX, NU>,
    /// Output matrix `C`.
    pub c: Matrix<S, NY, NX>,
    /// Feed-through `D` (acts on the previous `u - u0`); ignored unless `use_d`.
    pub d: Matrix<S, NY, NU>,
    /// Measurement-update gain `M` (MATLAB's `dlqe` `M`).
    pub m: Matrix<S, NX, NY>,
    /// Innovation correction of the time update, `L - A M`; ignored unless `use_cross`.
    pub cross: Matrix<S, NX, NY>,
    /// Input operating point `u0`.
    pub u0: [S; NU],
    /// Output operating point `y0` (the model maps `u - u0` to `y - y0`).
    pub y0: [S; NY],
    /// The folded measurement offset `y0 + b` (operating point plus sensor bias).
    pub y_offset: [S; NY],
    /// Whether `D` is non-zero.
    pub use_d: bool,
    /// Whether `L - A M` is non-zero.
    pub use_cross: bool,
}

impl<S: Scalar, const NX: usize, const NU: usize, const NY: usize> StationaryGains<S, NX, NU, NY> {
    /// Multiply-adds of one measurement update plus one time update.
    pub const fn multiply_adds(&self) -> usize {
        let mut n = NY * NX + NX * NY + NX * NX + NX * NU;
        if self.use_d {
            n += NY * NU;
        }
        if self.use_cross {
            n += NX * NY;
        }
        n
    }

    /// Converts every table to another scalar (for example f64 -> Q16).
    pub fn cast<T: Scalar>(&self) -> StationaryGains<T, NX, NU, NY> {
        StationaryGains {
            a: self.a.cast(),
            b: self.b.cast(),
            c: self.c.cast(),
            d: self.d.cast(),
            m: self.m.cast(),
            cross: self.cross.cast(),
            u0: cast_arr(&self.u0),
            y0: cast_arr(&self.y0),
            y_offset: cast_arr(&self.y_offset),
            use_d: self.use_d,
            use_cross: self.use_cross,
        }
    }

    /// Whether every table entry is finite.
    pub fn is_finite(&self) -> bool {
        self.a.is_finite()
            && self.b.is_finite()
            && self.c.is_finite()
            && self.d.is_finite()
            && self.m.is_finite()
            && self.cross.is_finite()
            && all_finite(&self.u0)
            && all_finite(&self.y0)
            && all_finite(&self.y_offset)
    }
}

fn cast_arr<S: Scalar, T: Scalar, const N: usize>(x: &[S; N]) -> [T; N] {
    core::array::from_fn(|i| T::from_f64(x[i].to_f64()))
}

/// What the filter did with the measurements so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FilterStatus {
    /// The last measurement update was rejected (non-finite measurement or
    /// result); the estimate is then the prediction.
    pub last_rejected: bool,
    /// Rejected measurement updates since construction or reset.
    pub rejected: u32,
    /// Rejected time updates (non-finite input or result).
    pub rejected_inputs: u32,
}

/// The stationary Kalman filter (thesis (5.15), corrected time update).
///
/// ```
/// use kestrel_core::{Matrix, StateEstimator};
/// use kestrel_kalman::{StationaryFilter, StationaryGains};
/// // A scalar random walk observed directly, gain M = 0.5.
/// let gains = StationaryGains {
///     a: Matrix::from_rows([[1.0]]), b: Matrix::from_rows([[0.0]]),
///     c: Matrix::from_rows([[1.0]]), d: Matrix::from_rows([[0.0]]),
///     m: Matrix::from_rows([[0.5]]), cross: Matrix::from_rows([[0.0]]),
///     u0: [0.0], y0: [0.0], y_offset: [0.0], use_d: false, use_cross: false,
/// };
/// let mut f = StationaryFilter::<f64, 1, 1, 1>::new(gains, [0.0]);
/// f.measurement_update(&[2.0]).unwrap();
/// assert_eq!(f.estimate(), &[1.0]);
/// // A NaN measurement is refused and the estimate kept.
/// assert!(f.measurement_update(&[f64::NAN]).is_err());
/// assert_eq!(f.estimate(), &[1.0]);
/// assert!(f.status().last_rejected);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StationaryFilter<S, const NX: usize, const NU: usize, const NY: usize> {
    gains: StationaryGains<S, NX, NU, NY>,
    x: [S; NX],
    du_last: [S; NU],
    innovation: [S; NY],
    status: FilterStatus,
}

impl<S: Scalar, const NX: usize, const NU: usize, const NY: usize> StationaryFilter<S, NX, NU, NY> {
    /// A filter with the given tables and initial prediction `x_{0|-1}`
    /// (deviation from the operating point; usually zeros).
    pub const fn new(gains: StationaryGains<S, NX, NU, NY>, x0: [S; NX]) -> Self {
        StationaryFilter {
            gains,
            x: x0,
            du_last: [S::ZERO; NU],
            innovation: [S::ZERO; NY],
            status: FilterStatus {
                last_rejected: false,
                rejected: 0,
                rejected_inputs: 0,
            },
        }
    }

    /// The tables.
    pub const fn gains(&self) -> &StationaryGains<S, NX, NU, NY> {
        &self.gains
    }

    /// Rejection flags and counters.
    pub const fn status(&self) -> FilterStatus {
        self.status
    }

    /// The state estimate as an array.
    pub const fn state(&self) -> &[S; NX] {
        &self.x
    }

    /// The innovation of the last accepted measurement update (zero after a time update).
    pub const fn innovation(&self) -> &[S; NY] {
        &self.innovation
    }

    /// Measurement update with `y_k` in measured units (offset and bias are removed here).
    ///
    /// A non-finite `y` (or a non-finite result) leaves the estimate at the
    /// prediction, sets [`FilterStatus::last_rejected`] and returns
    /// [`Error::NonFinite`].
    pub fn update(&mut self, y: &[S; NY]) -> Result<(), Error> {
        let g = &self.gains;
        let mut e = [S::ZERO; NY];
        for (i, ei) in e.iter_mut().enumerate() {
            let mut acc = y[i] - g.y_offset[i];
            acc -= S::dot(&g.c.data[i], &self.x);
            if g.use_d {
                acc -= S::dot(&g.d.data[i], &self.du_last);
            }
            *ei = acc;
        }
        let mut x = self.x;
        for (xi, mrow) in x.iter_mut().zip(g.m.data.iter()) {
            *xi += S::dot(mrow, &e);
        }
        if !(all_finite(y) && all_finite(&e) && all_finite(&x)) {
            self.innovation = [S::ZERO; NY];
            self.status.last_rejected = true;
            self.status.rejected = self.status.rejected.saturating_add(1);
            return Err(Error::NonFinite);
        }
        self.x = x;
        self.innovation = e;
        self.status.last_rejected = false;
        Ok(())
    }

    /// Time update with the input `u_k` in actuator units (`u0` is removed here).
    ///
    /// A non-finite `u` (or result) keeps the estimate and returns [`Error::NonFinite`].
    pub fn predict(&mut self, u: &[S; NU]) -> Result<(), Error> {
        let g = &self.gains;
        let mut du = [S::ZERO; NU];
        for (i, d) in du.iter_mut().enumerate() {
            *d = u[i] - g.u0[i];
        }
        let mut x = [S::ZERO; NX];
        for (i, xi) in x.iter_mut().enumerate() {
            let mut acc = S::dot(&g.a.data[i], &self.x) + S::dot(&g.b.data[i], &du);
            if g.use_cross {
                acc += S::dot(&g.cross.data[i], &self.innovation);
            }
            *xi = acc;
        }
        if !(all_finite(u) && all_finite(&x)) {
            self.status.rejected_inputs = self.status.rejected_inputs.saturating_add(1);
            return Err(Error::NonFinite);
        }
        self.x = x;
        self.du_last = du;
        self.innovation = [S::ZERO; NY];
        Ok(())
    }

    /// The estimated output `y0 + C x + D du` in measured units, without the
    /// sensor bias (for example the filtered body rates p, q, r). Costs
    /// `NY NX` multiply-adds (plus `NY NU` with `D`).
    pub fn output_estimate(&self) -> [S; NY] {
        let g = &self.gains;
        core::array::from_fn(|i| {
            let mut acc = g.y0[i] + S::dot(&g.c.data[i], &self.x);
            if g.use_d {
                acc += S::dot(&g.d.data[i], &self.du_last);
            }
            acc
        })
    }

    /// Resets the estimate, the held input and the status.
    pub fn reset_to(&mut self, x0: [S; NX]) {
        self.x = x0;
        self.du_last = [S::ZERO; NU];
        self.innovation = [S::ZERO; NY];
        self.status = FilterStatus::default();
    }
}

impl<S: Scalar, const NX: usize, const NU: usize, const NY: usize> StateEstimator
    for StationaryFilter<S, NX, NU, NY>
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
    fn measurement_update(&mut self, y: &[S]) -> Result<(), Error> {
        let y: &[S; NY] = y.try_into().map_err(|_| Error::DimensionMismatch {
            expected: NY,
            found: y.len(),
        })?;
        self.update(y)
    }
    fn time_update(&mut self, u: &[S]) -> Result<(), Error> {
        let u: &[S; NU] = u.try_into().map_err(|_| Error::DimensionMismatch {
            expected: NU,
            found: u.len(),
        })?;
        self.predict(u)
    }
    fn estimate(&self) -> &[S] {
        &self.x
    }
    fn reset(&mut self, x0: &[S]) -> Result<(), Error> {
        check_len(x0, NX)?;
        if !all_finite(x0) {
            return Err(Error::NonFinite);
        }
        let mut x = [S::ZERO; NX];
        for (xi, v) in x.iter_mut().zip(x0) {
            *xi = *v;
        }
        self.reset_to(x);
        Ok(())
    }
}
