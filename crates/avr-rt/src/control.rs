//! The control-loop composition run once per 20 ms period:
//!
//! 1. failsafe decision ([`Failsafe`], with the optional gyro plausibility
//!    check [`GyroCheck`]);
//! 2. **estimator stage**: gyro bias removal and the estimator's measurement
//!    update, plus (after the law) its time update: together the stationary
//!    Kalman step (kestrel-kalman's `StationaryFilter` in the firmware);
//! 3. **solver stage**: the control law alone (the fast gradient method of
//!    [`crate::law::FgmLaw`] in the firmware; [`crate::interim`] for tests);
//! 4. mixer (`pwm = offset + M u + t * throttle`) and saturation to the PWM limits.
//!
//! Each stage is timed with a [`CycleClock`], on the AVR the Timer1 counter.

use crate::cycles::CycleClock;
use crate::frame::{Command, status};
pub use crate::law::LawInfo;
use crate::output::{Decision, Failsafe, FailsafeReason, PwmLimits, RtScalar, SafeOutput};
use kestrel_core::{ControlLaw, Error, Matrix, StateEstimator};

/// Maps the law's output `u` and the throttle to the four pulses:
/// `pwm = offset + m u + throttle_gain * throttle`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mixer<S, const NU: usize> {
    /// Pulse offsets (trim), microseconds.
    pub offset: [S; 4],
    /// Input matrix from the law's output to the pulses.
    pub m: Matrix<S, 4, NU>,
    /// How the throttle enters each pulse (1 for the ESCs, 0 for the servo).
    pub throttle_gain: [S; 4],
}

impl<S: RtScalar, const NU: usize> Mixer<S, NU> {
    /// Applies the mixer.
    pub fn mix(&self, u: &[S; NU], throttle: S) -> [S; 4] {
        let mut p = self.offset;
        self.m.mul_vec_acc(u, &mut p);
        for (pi, g) in p.iter_mut().zip(self.throttle_gain) {
            *pi = pi.mul_add(g, throttle);
        }
        p
    }
}

/// A plausibility check of the gyro reading, per axis: a sensor fault is
/// an axis that reads at or beyond the gyro's `full_scale` (railed: at
/// once, as a non-finite value is), or that repeats the previous frame's
/// reading bit for bit in `stuck_periods` consecutive frames (stuck). The
/// failsafe engages ([`Failsafe::sensor_fault`]) and releases with the
/// first frame whose every axis is in range and not a repeat.
///
/// A railed reading is acted on at once because the law would otherwise
/// fight a rate the aircraft does not have with full authority (in the
/// HIL, nine periods of a pitch gyro railed at 2000 deg/s turned the
/// aircraft over). A live MEMS gyro's noise spans several of its LSBs, so
/// a bit-identical reading repeats by chance with a probability below
/// about 0.1 per sample and axis: ten repeats in a row (the default,
/// 200 ms at 50 Hz) about 1e-10, while a stuck sensor repeats its code
/// every time.
///
/// ```
/// use kestrel_avr_rt::control::GyroCheck;
/// let mut c = GyroCheck::new(34.9, 3);
/// assert!(c.update(&[0.01, 0.0, 0.0]));
/// assert!(c.update(&[0.01, 0.1, 0.0])); // p repeats: 1
/// assert!(c.update(&[0.01, 0.2, 0.0])); // 2
/// assert!(!c.update(&[0.01, 0.3, 0.0])); // 3: stuck
/// assert!(c.update(&[0.02, 0.3, 0.1])); // live again (q's first repeat)
/// assert!(!c.update(&[0.03, 0.4, 40.0])); // r railed: at once
/// assert!(c.update(&[0.04, 0.5, 0.2]));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroCheck {
    /// Full scale of the gyro in rad/s (a reading with `|g| >= full_scale`,
    /// or a non-finite one, is railed).
    pub full_scale: f32,
    /// Consecutive repeats of one reading that make an axis stuck.
    pub stuck_periods: u8,
    last: [u32; 3],
    repeats: [u8; 3],
}

impl Default for GyroCheck {
    /// 2000 deg/s full scale (34.9 rad/s, the widest range of the
    /// MPU-6000 family), stuck after 10 repeats (200 ms at 50 Hz).
    fn default() -> Self {
        GyroCheck::new(34.9, 10)
    }
}

impl GyroCheck {
    /// A check with the given full scale (rad/s) and repeat count (0 is
    /// taken as 1).
    pub const fn new(full_scale: f32, stuck_periods: u8) -> Self {
        GyroCheck {
            full_scale,
            stuck_periods: if stuck_periods == 0 { 1 } else { stuck_periods },
            // A NaN pattern: no finite reading repeats it.
            last: [u32::MAX; 3],
            repeats: [0; 3],
        }
    }

    /// Takes one frame's reading; `false` if an axis is now railed or stuck.
    pub fn update(&mut self, gyro: &[f32; 3]) -> bool {
        let mut ok = true;
        for ((g, last), n) in gyro.iter().zip(&mut self.last).zip(&mut self.repeats) {
            let bits = g.to_bits();
            *n = if bits == *last {
                n.saturating_add(1)
            } else {
                0
            };
            *last = bits;
            ok &= *n < self.stuck_periods && g.abs() < self.full_scale;
        }
        ok
    }
}

/// The result of one period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PeriodOutput {
    /// The four saturated pulses (ESC 1-3, servo) in microseconds.
    pub pwm: [u16; 4],
    /// [`status`] bits for the reply frame.
    pub status: u8,
    /// Cycles of the estimator stage.
    pub kalman_cycles: u32,
    /// Cycles of the solver stage.
    pub solver_cycles: u32,
    /// The law's iteration count.
    pub iterations: u16,
}

/// The rate loop: bias removal, estimator, law, mixer, saturation, failsafe.
///
/// `NX` states, `NU` law outputs; three measured rates; the law reads the
/// reference `[p_ref, q_ref, r_ref, throttle]`.
#[derive(Clone, Debug)]
pub struct RateLoop<S, E, L, const NU: usize> {
    /// The estimator (stationary Kalman filter).
    pub estimator: E,
    /// The control law.
    pub law: L,
    /// Gyro bias subtracted from each measurement.
    pub bias: [S; 3],
    /// Output mixer.
    pub mixer: Mixer<S, NU>,
    /// PWM limits.
    pub limits: PwmLimits,
    /// Failsafe pulses.
    pub safe: SafeOutput,
    /// The gyro plausibility check, if any (`None` after [`RateLoop::new`]).
    pub gyro_check: Option<GyroCheck>,
    failsafe: Failsafe,
    last_pwm: [u16; 4],
}

impl<S, E, L, const NU: usize> RateLoop<S, E, L, NU>
where
    S: RtScalar,
    E: StateEstimator<Scalar = S>,
    L: ControlLaw<Scalar = S> + LawInfo,
{
    /// A loop from its parts; checks that the dimensions agree.
    pub fn new(
        estimator: E,
        law: L,
        bias: [S; 3],
        mixer: Mixer<S, NU>,
        limits: PwmLimits,
        safe: SafeOutput,
    ) -> Result<Self, Error> {
        let dims = [
            (estimator.ny(), 3),
            (estimator.nu(), NU),
            (law.nu(), NU),
            (law.nr(), 4),
            (law.nx(), estimator.nx()),
        ];
        for (found, expected) in dims {
            if found != expected {
                return Err(Error::DimensionMismatch { expected, found });
            }
        }
        let last_pwm = safe.pwm(&limits);
        Ok(RateLoop {
            estimator,
            law,
            bias,
            mixer,
            limits,
            safe,
            gyro_check: None,
            failsafe: Failsafe::new(),
            last_pwm,
        })
    }

    /// The failsafe state.
    pub fn failsafe(&self) -> &Failsafe {
        &self.failsafe
    }

    /// Runs one period with the fresh command, if one arrived since the last
    /// period (`None`: dropped or corrupted frame).
    pub fn period(&mut self, cmd: Option<&Command>, clock: &impl CycleClock) -> PeriodOutput {
        let mut out = PeriodOutput::default();
        let finite = cmd.map(Command::is_finite);
        // The sensor check sees every finite frame's reading.
        let sensor_ok = match (cmd, finite, self.gyro_check.as_mut()) {
            (Some(c), Some(true), Some(check)) => check.update(&c.gyro),
            _ => true,
        };
        let decision = if sensor_ok {
            self.failsafe.on_tick(finite)
        } else {
            self.failsafe.sensor_fault()
        };
        let (cmd, recovered) = match (decision, cmd) {
            (Decision::Run { recovered }, Some(c)) => (c, recovered),
            (Decision::Hold, _) => {
                out.pwm = self.last_pwm;
                out.status = status::HOLD;
                return out;
            }
            _ => return self.safe_output(out),
        };
        // Conversions from the wire format are I/O, outside the timed stages.
        let g = cmd.gyro.map(S::from_f32_fast);
        let r = [
            S::from_f32_fast(cmd.reference[0]),
            S::from_f32_fast(cmd.reference[1]),
            S::from_f32_fast(cmd.reference[2]),
            S::from_f32_fast(cmd.throttle),
        ];
        // black_box pins the work between the clock reads (the compiler
        // may otherwise move pure arithmetic across them).
        let (g, r) = core::hint::black_box((g, r));
        // The law's outputs, set up outside the timed stages.
        let mut u = [S::ZERO; NU];
        let t0 = clock.now();
        let y = [
            g[0] - self.bias[0],
            g[1] - self.bias[1],
            g[2] - self.bias[2],
        ];
        if recovered {
            // Restart the estimator at the operating point (the filter
            // converges within a few samples) and clear the law's memory.
            let x0 = [S::ZERO; 16];
            let nx = self.estimator.nx().min(16);
            let _ = self.estimator.reset(&x0[..nx]);
            self.law.restart();
        }
        let est =
            core::hint::black_box(self.estimator.measurement_update(core::hint::black_box(&y)));
        core::hint::black_box(self.estimator.estimate());
        let t1 = clock.now();
        let law = est.and_then(|_| self.law.control(self.estimator.estimate(), &r, &mut u));
        // Pins the law's work before the clock read without copying its
        // outputs through the caller's frame (a copy of the whole
        // (result, u) tuple cost hundreds of cycles in the firmware's
        // large frame, inside the solver stage).
        let law = core::hint::black_box(law);
        core::hint::black_box(&mut u);
        let t2 = clock.now();
        let tu = law.and_then(|_| self.estimator.time_update(&u));
        let tu = core::hint::black_box(tu);
        let t3 = clock.now();
        // The Kalman step is the measurement update plus the time update.
        out.kalman_cycles = t1.wrapping_sub(t0).wrapping_add(t3.wrapping_sub(t2));
        out.solver_cycles = t2.wrapping_sub(t1);
        out.iterations = self.law.iterations();
        if tu.is_err() {
            self.failsafe.non_finite_output();
            return self.safe_output(out);
        }
        match self.limits.saturate(&self.mixer.mix(&u, r[3])) {
            Some(p) => {
                out.pwm = p;
                self.last_pwm = p;
                out
            }
            None => {
                self.failsafe.non_finite_output();
                self.safe_output(out)
            }
        }
    }

    fn safe_output(&mut self, mut out: PeriodOutput) -> PeriodOutput {
        out.pwm = self.safe.pwm(&self.limits);
        self.last_pwm = out.pwm;
        out.status |= status::FAILSAFE
            | match self.failsafe.active() {
                Some(FailsafeReason::NonFinite) => status::NON_FINITE,
                Some(FailsafeReason::Timeout) | None => status::TIMEOUT,
                // FAILSAFE alone: the gyro check refused the reading.
                Some(FailsafeReason::Sensor) => 0,
            };
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interim::{PiRateLaw, RateObserver};

    struct Clock;
    impl CycleClock for Clock {
        fn now(&self) -> u32 {
            0
        }
    }

    type Loop = RateLoop<f32, RateObserver<f32>, PiRateLaw<f32>, 3>;

    fn rate_loop() -> Loop {
        let mixer = Mixer {
            offset: [0.0, 0.0, 0.0, 1500.0],
            m: Matrix::from_fn(|i, j| if i == j { 1.0 } else { 0.0 }),
            throttle_gain: [1.0, 1.0, 1.0, 0.0],
        };
        let law = PiRateLaw::new([100.0f32; 3], [0.0; 3], [50.0; 3]);
        let mut l = RateLoop::new(
            RateObserver::new([0.5f32; 3], [0.02; 3]),
            law,
            [0.0; 3],
            mixer,
            PwmLimits::default(),
            SafeOutput::default(),
        )
        .unwrap();
        l.gyro_check = Some(GyroCheck::new(34.9, 3));
        l
    }

    fn cmd(gyro: [f32; 3]) -> Command {
        Command {
            gyro,
            reference: [0.0; 3],
            throttle: 1400.0,
        }
    }

    #[test]
    fn stuck_gyro_engages_the_failsafe_until_it_is_live_again() {
        let mut l = rate_loop();
        let safe = SafeOutput::default().pwm(&PwmLimits::default());
        assert_eq!(l.period(Some(&cmd([0.1, 0.2, 0.3])), &Clock).status, 0);
        // q stuck: three repeats make the fault.
        for k in 0..3 {
            let out = l.period(Some(&cmd([0.1 + k as f32, 0.2, 0.3 + k as f32])), &Clock);
            if k < 2 {
                assert_eq!(out.status, 0, "repeat {k}");
            } else {
                assert_eq!(out.status, status::FAILSAFE, "only FAILSAFE: the sensor");
                assert_eq!(out.pwm, safe);
                assert_eq!(l.failsafe().active(), Some(FailsafeReason::Sensor));
            }
        }
        // Still stuck: stays in the failsafe; one missing frame does not
        // change the reason.
        assert_eq!(l.period(Some(&cmd([5.0, 0.2, 5.0])), &Clock).pwm, safe);
        assert_eq!(l.period(None, &Clock).pwm, safe);
        // Live again: recovery at once.
        let out = l.period(Some(&cmd([0.0, 0.21, 0.0])), &Clock);
        assert_eq!(out.status, 0);
        assert_eq!(l.failsafe().active(), None);
    }

    #[test]
    fn railed_gyro_engages_the_failsafe() {
        let mut l = rate_loop();
        assert_eq!(l.period(Some(&cmd([0.0, 0.1, 0.0])), &Clock).status, 0);
        for k in 0..3 {
            let g = [0.01 * k as f32, -34.9 - k as f32, 0.02 * k as f32];
            let out = l.period(Some(&cmd(g)), &Clock);
            assert_eq!(out.status, status::FAILSAFE, "frame {k}");
        }
        assert_eq!(l.period(Some(&cmd([0.0, 0.1, 0.0])), &Clock).status, 0);
        // Without the check a railed reading is flown on.
        let mut l = rate_loop();
        l.gyro_check = None;
        for k in 0..5 {
            let out = l.period(Some(&cmd([0.0, -34.9, 0.0])), &Clock);
            assert_eq!(out.status, 0, "frame {k}");
            assert!(out.pwm.iter().all(|&p| (1000..=2000).contains(&p)));
        }
    }

    #[test]
    fn non_finite_gyro_is_non_finite_not_a_sensor_fault() {
        let mut l = rate_loop();
        let out = l.period(Some(&cmd([f32::INFINITY, 0.0, 0.0])), &Clock);
        assert_eq!(out.status, status::FAILSAFE | status::NON_FINITE);
        let out = l.period(Some(&cmd([0.0, 0.1, 0.2])), &Clock);
        assert_eq!(out.status, 0);
    }
}
