//! The control-loop composition run once per 20 ms period:
//!
//! 1. failsafe decision ([`Failsafe`]);
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
        let decision = self.failsafe.on_tick(cmd.map(Command::is_finite));
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
                _ => status::TIMEOUT,
            };
        out
    }
}
