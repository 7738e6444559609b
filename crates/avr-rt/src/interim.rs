//! **Interim** estimator and control law, built from `kestrel-core` only.
//!
//! They stand in for the stationary Kalman filter of `kestrel-kalman` and
//! the explicit MPC / fast gradient of `kestrel-empc` / `kestrel-fgm` until
//! those crates' `no_std` parts are available, so that the firmware loop,
//! the protocol, the failsafe and the cycle measurements are real. They are
//! *not* the thesis's controller and their cycle counts do not measure the
//! issue's targets.
//!
//! - [`RateObserver`]: a constant-gain observer for the per-axis model
//!   `w[k+1] = w[k] + g u[k]` (`g = Ts / I`, `u` the virtual torque) with
//!   measurement `y = w`: the stationary Kalman filter of that model, with a
//!   diagonal gain chosen offline.
//! - [`PiRateLaw`]: per-axis proportional-integral rate law giving virtual
//!   torques, with a clamped integrator (anti-windup).

use crate::law::LawInfo;
use kestrel_core::{ControlLaw, Error, Scalar, StateEstimator, all_finite, check_len};

/// Constant-gain rate observer (interim stand-in for the stationary Kalman step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateObserver<S> {
    /// Measurement-update gain per axis (0..1).
    pub gain: [S; 3],
    /// Input gain per axis (`Ts / I`).
    pub input_gain: [S; 3],
    x: [S; 3],
}

impl<S: Scalar> RateObserver<S> {
    /// An observer starting at zero rates.
    pub fn new(gain: [S; 3], input_gain: [S; 3]) -> Self {
        RateObserver {
            gain,
            input_gain,
            x: [S::ZERO; 3],
        }
    }
}

impl<S: Scalar> StateEstimator for RateObserver<S> {
    type Scalar = S;
    fn nx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        3
    }
    fn ny(&self) -> usize {
        3
    }
    fn measurement_update(&mut self, y: &[S]) -> Result<(), Error> {
        check_len(y, 3)?;
        if !all_finite(y) {
            return Err(Error::NonFinite);
        }
        for ((x, yi), l) in self.x.iter_mut().zip(y).zip(self.gain) {
            *x = x.mul_add(l, *yi - *x);
        }
        Ok(())
    }
    fn time_update(&mut self, u: &[S]) -> Result<(), Error> {
        check_len(u, 3)?;
        if !all_finite(u) {
            return Err(Error::NonFinite);
        }
        for ((x, ui), g) in self.x.iter_mut().zip(u).zip(self.input_gain) {
            *x = x.mul_add(g, *ui);
        }
        Ok(())
    }
    fn estimate(&self) -> &[S] {
        &self.x
    }
    fn reset(&mut self, x0: &[S]) -> Result<(), Error> {
        check_len(x0, 3)?;
        self.x.copy_from_slice(x0);
        Ok(())
    }
}

/// Per-axis PI rate law (interim stand-in for the MPC).
///
/// Not kestrel-tricopter-model's `RatePid`, the simulator's baseline
/// controller, on purpose: that one outputs pulses through its mixer, cuts
/// the motors at low throttle and holds an axis's integral while the mixer
/// clips it; this one outputs virtual torques with a clamped integrator, in
/// `mul_add` form for fixed point, for the firmware's loop (this crate does
/// not depend on the model crate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiRateLaw<S> {
    /// Proportional gains (torque per rad/s).
    pub kp: [S; 3],
    /// Integral gains times the sample time.
    pub ki_ts: [S; 3],
    /// Integrator limit (absolute, torque units).
    pub i_max: [S; 3],
    integ: [S; 3],
}

impl<S: Scalar> PiRateLaw<S> {
    /// A law with empty integrators.
    pub fn new(kp: [S; 3], ki_ts: [S; 3], i_max: [S; 3]) -> Self {
        PiRateLaw {
            kp,
            ki_ts,
            i_max,
            integ: [S::ZERO; 3],
        }
    }
}

impl<S: Scalar> ControlLaw for PiRateLaw<S> {
    type Scalar = S;
    fn nx(&self) -> usize {
        3
    }
    fn nr(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        3
    }
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        check_len(x, 3)?;
        check_len(r, 4)?;
        check_len(u, 3)?;
        if !all_finite(x) || !all_finite(r) {
            return Err(Error::NonFinite);
        }
        for i in 0..3 {
            let e = r[i] - x[i];
            let lim = self.i_max[i];
            self.integ[i] = self.integ[i].mul_add(self.ki_ts[i], e).clamp(-lim, lim);
            u[i] = self.integ[i].mul_add(self.kp[i], e);
        }
        Ok(())
    }
}

impl<S: Scalar> LawInfo for PiRateLaw<S> {
    fn restart(&mut self) {
        self.integ = [S::ZERO; 3];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::Q16;

    #[test]
    fn observer_converges_to_a_constant_measurement() {
        let mut o = RateObserver::new([0.5f64; 3], [0.0; 3]);
        for _ in 0..40 {
            o.measurement_update(&[1.0, -2.0, 0.5]).unwrap();
            o.time_update(&[0.0; 3]).unwrap();
        }
        for (x, y) in o.estimate().iter().zip([1.0, -2.0, 0.5]) {
            assert!((x - y).abs() < 1e-9);
        }
        assert_eq!(
            o.measurement_update(&[f64::NAN, 0.0, 0.0]),
            Err(Error::NonFinite)
        );
        assert!(matches!(
            o.measurement_update(&[0.0; 2]),
            Err(Error::DimensionMismatch { .. })
        ));
    }

    #[test]
    fn pi_law_closes_a_first_order_loop_in_fixed_point_like_f64() {
        // Plant w+ = w + 0.02 u; the integrator removes a constant disturbance.
        fn run<S: Scalar>() -> f64 {
            let mut law = PiRateLaw::new(
                [S::from_f64(10.0); 3],
                [S::from_f64(0.2); 3],
                [S::from_f64(50.0); 3],
            );
            let mut w = [0.0f64; 3];
            let mut u = [S::ZERO; 3];
            for _ in 0..400 {
                let x = w.map(S::from_f64);
                let r = [
                    S::from_f64(1.0),
                    S::from_f64(-1.0),
                    S::from_f64(0.5),
                    S::ZERO,
                ];
                law.control(&x, &r, &mut u).unwrap();
                for i in 0..3 {
                    w[i] += 0.02 * (u[i].to_f64() - 3.0);
                }
            }
            (w[0] - 1.0).abs() + (w[1] + 1.0).abs() + (w[2] - 0.5).abs()
        }
        assert!(run::<f64>() < 1e-3);
        assert!(run::<Q16>() < 1e-2);
    }
}
