//! A baseline body-rate controller like ArduCopter's ACRO mode: a PI law on
//! each body rate with an integrator limit, output through the [`Mixer`].
//!
//! Run-time code: `no_std`, allocation-free, generic over [`Scalar`].

use crate::mixer::{Mixer, MixerOutput, VirtualInput};
use kestrel_core::{ControlLaw, Error, Scalar, all_finite, check_len};

/// Gains of [`RatePid`], per axis `[roll, pitch, yaw]`.
///
/// Units: `kp` in us per rad/s, `ki` in us per rad, `imax` in us.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RatePidGains<S> {
    /// Proportional gains.
    pub kp: [S; 3],
    /// Integral gains.
    pub ki: [S; 3],
    /// Integrator limits (the integral term is clamped to `+-imax`).
    pub imax: [S; 3],
    /// Controller period in seconds (0.02 for the thesis's 50 Hz loop).
    pub dt: S,
    /// Below this throttle (us) the aircraft is taken to be on the ground:
    /// the integrators are reset and the motors get the lowest pulse.
    pub throttle_cut: S,
}

impl Default for RatePidGains<f64> {
    /// Gains for the default aircraft at 50 Hz: with the hover virtual
    /// rate model's `B` (about 0.28, 0.24, 0.05 rad/s^2 per us on roll,
    /// pitch, yaw) the loop crossovers are about 8, 8 and 5 rad/s.
    fn default() -> Self {
        RatePidGains {
            kp: [30.0, 32.0, 90.0],
            ki: [45.0, 48.0, 60.0],
            imax: [100.0, 100.0, 100.0],
            dt: 0.02,
            throttle_cut: 1100.0,
        }
    }
}

/// ArduCopter-ACRO-like rate PI controller.
///
/// As a [`ControlLaw`]: `x = [p, q, r]` measured body rates (rad/s),
/// `r = [p_ref, q_ref, r_ref, throttle]` (rad/s, rad/s, rad/s, us),
/// `u = [pwm1, pwm2, pwm3, servo]` (us, saturated by the mixer).
///
/// ```
/// use kestrel_core::ControlLaw;
/// use kestrel_tricopter_model::{Mixer, RatePid, RatePidGains};
/// let mut pid = RatePid::new(RatePidGains::default(), Mixer::new([0.0, 0.0, 0.0, 1500.0]));
/// let mut u = [0.0; 4];
/// // Rolling too slowly to the right: more thrust on the left motor (2).
/// pid.control(&[0.0, 0.0, 0.0], &[0.5, 0.0, 0.0, 1500.0], &mut u).unwrap();
/// assert!(u[1] > 1500.0 && u[2] < 1500.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RatePid<S> {
    /// The gains.
    pub gains: RatePidGains<S>,
    /// The mixer the virtual inputs go through.
    pub mixer: Mixer<S>,
    integ: [S; 3],
    last_virtual: VirtualInput<S>,
    last_output: MixerOutput<S>,
}

impl<S: Scalar> RatePid<S> {
    /// A controller with zero integrators.
    pub fn new(gains: RatePidGains<S>, mixer: Mixer<S>) -> Self {
        RatePid {
            gains,
            mixer,
            integ: [S::ZERO; 3],
            last_virtual: VirtualInput::default(),
            last_output: MixerOutput::default(),
        }
    }

    /// Resets the integrators.
    pub fn reset(&mut self) {
        self.integ = [S::ZERO; 3];
    }

    /// The integral terms (us), `[roll, pitch, yaw]`.
    pub fn integrators(&self) -> [S; 3] {
        self.integ
    }

    /// The virtual inputs of the last [`ControlLaw::control`] call.
    pub fn last_virtual(&self) -> VirtualInput<S> {
        self.last_virtual
    }

    /// The mixer output (with saturation flags) of the last call.
    pub fn last_output(&self) -> MixerOutput<S> {
        self.last_output
    }

    /// One controller period: measured rates `y`, rate references `reference`
    /// and `throttle` in, mixer output out.
    pub fn update(
        &mut self,
        y: &[S; 3],
        reference: &[S; 3],
        throttle: S,
    ) -> Result<MixerOutput<S>, Error> {
        if !all_finite(y) || !all_finite(reference) || !throttle.is_finite() {
            return Err(Error::NonFinite);
        }
        let g = &self.gains;
        if throttle < g.throttle_cut {
            self.reset();
            self.last_virtual = VirtualInput {
                throttle,
                ..VirtualInput::default()
            };
            let mut out = self.mixer.mix(&self.last_virtual);
            for i in 0..3 {
                out.pwm[i] = self.mixer.lower[i];
            }
            self.last_output = out;
            return Ok(out);
        }
        let mut next = self.integ;
        let mut v = [S::ZERO; 3];
        for i in 0..3 {
            let e = reference[i] - y[i];
            next[i] = (next[i] + g.ki[i] * e * g.dt).clamp(-g.imax[i], g.imax[i]);
            v[i] = g.kp[i] * e + next[i];
        }
        let vi = VirtualInput {
            roll: v[0],
            pitch: v[1],
            yaw: v[2],
            throttle,
        };
        let out = self.mixer.mix(&vi);
        // Conditional integration (anti-windup): keep the old integral on
        // the axes whose outputs were clipped.
        let motors = out.saturated[0] || out.saturated[1] || out.saturated[2];
        for i in 0..3 {
            let clipped = if i == 2 { out.saturated[3] } else { motors };
            if !clipped {
                self.integ[i] = next[i];
            }
        }
        self.last_virtual = vi;
        self.last_output = out;
        Ok(out)
    }
}

impl<S: Scalar> ControlLaw for RatePid<S> {
    type Scalar = S;
    fn nx(&self) -> usize {
        3
    }
    fn nr(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        4
    }
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        check_len(x, 3)?;
        check_len(r, 4)?;
        check_len(u, 4)?;
        let y = [x[0], x[1], x[2]];
        let reference = [r[0], r[1], r[2]];
        let out = self.update(&y, &reference, r[3])?;
        u.copy_from_slice(&out.pwm);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pid() -> RatePid<f64> {
        RatePid::new(RatePidGains::default(), Mixer::new([0.0, 0.0, 0.0, 1500.0]))
    }

    #[test]
    fn pi_law_and_integrator_limit() {
        let mut c = pid();
        let g = c.gains;
        let out = c.update(&[0.0; 3], &[0.1, 0.0, 0.0], 1500.0).unwrap();
        let want_roll = g.kp[0] * 0.1 + g.ki[0] * 0.1 * g.dt;
        let v = c.last_virtual();
        assert!((v.roll - want_roll).abs() < 1e-12);
        assert!((c.mixer.unmix(&out.pwm).roll - want_roll).abs() < 1e-9);
        for _ in 0..10_000 {
            c.update(&[0.0; 3], &[0.1, -0.1, 0.1], 1500.0).unwrap();
        }
        let i = c.integrators();
        assert!((i[0] - g.imax[0]).abs() < 1e-12);
        assert!((i[1] + g.imax[1]).abs() < 1e-12);
        assert!((i[2] - g.imax[2]).abs() < 1e-12);
    }

    #[test]
    fn throttle_cut_resets_and_stops_motors() {
        let mut c = pid();
        c.update(&[0.0; 3], &[1.0, 1.0, 1.0], 1500.0).unwrap();
        assert!(c.integrators()[0] != 0.0);
        let out = c.update(&[0.0; 3], &[1.0, 1.0, 1.0], 1000.0).unwrap();
        assert_eq!(c.integrators(), [0.0; 3]);
        assert_eq!(&out.pwm[..3], &[1000.0; 3]);
        assert_eq!(out.pwm[3], 1500.0);
    }

    #[test]
    fn anti_windup_holds_integral_when_saturated() {
        let mut c = pid();
        // Throttle at the top: motors clip, roll/pitch integrators must not move.
        c.update(&[0.0; 3], &[1.0, 1.0, 0.0], 2000.0).unwrap();
        assert_eq!(c.integrators()[0], 0.0);
        assert_eq!(c.integrators()[1], 0.0);
    }

    #[test]
    fn control_law_checks_input() {
        let mut c = pid();
        let mut u = [0.0; 4];
        assert_eq!(
            c.control(&[0.0; 2], &[0.0; 4], &mut u),
            Err(Error::DimensionMismatch {
                expected: 3,
                found: 2
            })
        );
        assert_eq!(
            c.control(&[f64::NAN, 0.0, 0.0], &[0.0, 0.0, 0.0, 1500.0], &mut u),
            Err(Error::NonFinite)
        );
        assert_eq!(c.integrators(), [0.0; 3]);
        c.control(&[0.0; 3], &[0.0, 0.0, 0.0, 1500.0], &mut u)
            .unwrap();
        assert_eq!(u, [1500.0, 1500.0, 1500.0, 1500.0]);
        assert_eq!((c.nx(), c.nr(), c.nu()), (3, 4, 4));
    }
}
