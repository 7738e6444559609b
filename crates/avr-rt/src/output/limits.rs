//! [`PwmLimits`] (saturation of the pulses) and [`SafeOutput`] (the
//! failsafe's pulses).

use super::scalar::RtScalar;

/// Pulse-width limits in microseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PwmLimits {
    /// Lowest ESC pulse (motor stopped).
    pub esc_min: u16,
    /// Highest ESC pulse (full speed).
    pub esc_max: u16,
    /// Lowest servo pulse.
    pub servo_min: u16,
    /// Highest servo pulse.
    pub servo_max: u16,
}

impl Default for PwmLimits {
    /// The thesis's limits: ESC 1000-2000 us, servo 1200-1800 us.
    fn default() -> Self {
        PwmLimits {
            esc_min: 1000,
            esc_max: 2000,
            servo_min: 1200,
            servo_max: 1800,
        }
    }
}

impl PwmLimits {
    /// Rounds and clamps ESC 1-3 and the servo (in that order) to their
    /// limits; `None` if any value is not finite (the caller then goes to
    /// the failsafe). Crossed limits (`min > max`) give at most `max`.
    pub fn saturate<S: RtScalar>(&self, pwm: &[S; 4]) -> Option<[u16; 4]> {
        let mut out = [0u16; 4];
        for (i, (o, v)) in out.iter_mut().zip(pwm).enumerate() {
            let us = v.to_us()?;
            let (lo, hi) = if i < 3 {
                (self.esc_min, self.esc_max)
            } else {
                (self.servo_min, self.servo_max)
            };
            *o = crate::clamp::clamp(us, lo as i32, hi as i32) as u16;
        }
        Some(out)
    }
}

/// The output held while the failsafe is active.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SafeOutput {
    /// ESC pulse for the three motors.
    pub esc: u16,
    /// Servo pulse.
    pub servo: u16,
}

impl Default for SafeOutput {
    /// Motors stopped (1000 us), servo centred (1500 us).
    fn default() -> Self {
        SafeOutput {
            esc: 1000,
            servo: 1500,
        }
    }
}

impl SafeOutput {
    /// The four pulses, clamped to `limits` (so a misconfigured safe output
    /// still cannot leave them; with crossed limits, `min > max`, each
    /// pulse is at most its `max`, and there is no panic path).
    pub fn pwm(&self, limits: &PwmLimits) -> [u16; 4] {
        let e = crate::clamp::clamp(self.esc, limits.esc_min, limits.esc_max);
        [
            e,
            e,
            e,
            crate::clamp::clamp(self.servo, limits.servo_min, limits.servo_max),
        ]
    }
}
