//! The hover trim in the thesis's PWM convention, the input bounds around
//! it, and the actuation (trim + move + throttle, clipped to the ranges).

use crate::constants::pwm;
use crate::error::TricopterError;
use kestrel_mpc::{Bounds, MpcSettings, Parameter};
use kestrel_tricopter_model::{ESC_PWM_RANGE, SERVO_PWM_RANGE};
use nalgebra::{DMatrix, DVector};

/// The hover trim of a 4-input tricopter model (`[motor 1, motor 2,
/// motor 3, servo]`) in the thesis's convention (7.2): motor offsets from
/// the common throttle and the servo offset from its centre.
///
/// A model's `u0` comes in one of two conventions, told apart by size:
/// the thesis's relative one (motor entries are offsets of tens of
/// microseconds, e.g. `[15.63, 0.85, -16.01, ...]`), or absolute pulses as
/// kestrel-tricopter-model writes them (motor entries near the hover
/// throttle, above 500 us). Absolute motor pulses are split into the hover
/// throttle (their mean) and offsets; an absolute servo pulse (above 500
/// us) is taken relative to its centre, 1500 us.
///
/// ```
/// use kestrel_tricopter::TricopterTrim;
/// let t = TricopterTrim::from_u0(&[1490.0, 1500.0, 1510.0, 1520.0]).unwrap();
/// assert_eq!(t.hover_throttle, 1500.0);
/// assert_eq!(t.offsets, [-10.0, 0.0, 10.0, 20.0]);
/// // z = 0 at the hover throttle gives back the trim pulses.
/// assert_eq!(t.actuate(&[0.0; 4], 1500.0).unwrap().pwm, [1490.0, 1500.0, 1510.0, 1520.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TricopterTrim {
    /// The common throttle at hover (us); 0 when `u0` was relative.
    pub hover_throttle: f64,
    /// Offsets at hover: motors from the throttle, servo from 1500 us.
    pub offsets: [f64; 4],
}

/// Pulses sent to the aircraft for one input move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuation {
    /// `[pwm1, pwm2, pwm3, servo]` (us), inside the ESC and servo ranges.
    pub pwm: [f64; 4],
    /// Which pulses were clipped to their range.
    pub saturated: [bool; 4],
    /// The move actually applied (deviation from the trim after clipping),
    /// for the estimator's time update.
    pub applied: [f64; 4],
}

impl TricopterTrim {
    /// Reads the trim from a model's `u0` (see the type's documentation).
    pub fn from_u0(u0: &[f64]) -> Result<Self, TricopterError> {
        if u0.len() != 4 {
            return Err(TricopterError::dim(
                "tricopter u0",
                "4 entries [motor 1, motor 2, motor 3, servo]",
                format!("{} entries", u0.len()),
            ));
        }
        if u0.iter().any(|v| !v.is_finite()) {
            return Err(TricopterError::non_finite("tricopter u0"));
        }
        let absolute = u0[..3].iter().all(|&v| v > 500.0);
        let relative = u0[..3].iter().all(|&v| v.abs() <= 500.0);
        if !absolute && !relative {
            return Err(TricopterError::setting(
                "tricopter u0",
                format!(
                    "motor trims {:?} mix absolute pulses (> 500 us) and offsets from the throttle",
                    &u0[..3]
                ),
            ));
        }
        let hover = if absolute {
            (u0[0] + u0[1] + u0[2]) / 3.0
        } else {
            0.0
        };
        let servo = if u0[3] > 500.0 {
            u0[3] - pwm::SERVO_CENTER
        } else {
            u0[3]
        };
        Ok(TricopterTrim {
            hover_throttle: hover,
            offsets: [u0[0] - hover, u0[1] - hover, u0[2] - hover, servo],
        })
    }

    /// The input bounds (6.5)-(6.7) around this trim ([`pwm_bounds`] of
    /// the offsets).
    pub fn bounds(&self) -> Bounds {
        pwm_bounds(&self.offsets)
    }

    /// `settings` with the thesis's constraints: the PWM window around
    /// this trim as input bounds ([`TricopterTrim::bounds`]) and the
    /// throttle as the one extra parameter ([`throttle_parameter`]), so
    /// `theta = [x; r; throttle]`.
    pub fn constrain(&self, settings: MpcSettings) -> MpcSettings {
        MpcSettings {
            input_bounds: Some(self.bounds()),
            parameters: vec![throttle_parameter()],
            ..settings
        }
    }

    /// The pulses for the move `z` (deviation from the trim) at `throttle`:
    /// motors `throttle + offset_i + z_i`, servo `1500 + offset_4 + z_4`,
    /// each clipped to its range (ESC 1000-2000 us, servo 1200-1800 us).
    pub fn actuate(&self, z: &[f64], throttle: f64) -> Result<Actuation, TricopterError> {
        if z.len() != 4 {
            return Err(TricopterError::dim(
                "input move",
                "4 entries",
                format!("{}", z.len()),
            ));
        }
        if z.iter().any(|v| !v.is_finite()) || !throttle.is_finite() {
            return Err(TricopterError::non_finite("input move or throttle"));
        }
        let mut out = Actuation {
            pwm: [0.0; 4],
            saturated: [false; 4],
            applied: [0.0; 4],
        };
        for (i, zi) in z.iter().enumerate() {
            let (base, (lo, hi)) = if i < 3 {
                (throttle + self.offsets[i], ESC_PWM_RANGE)
            } else {
                (pwm::SERVO_CENTER + self.offsets[3], SERVO_PWM_RANGE)
            };
            let raw = base + zi;
            let c = raw.clamp(lo, hi);
            out.saturated[i] = c != raw;
            out.pwm[i] = c;
            out.applied[i] = c - base;
        }
        Ok(out)
    }
}

/// The tricopter's bounds (6.5)-(6.7) around the trim `offsets` of a
/// 4-input model whose inputs are `[motor 1, motor 2, motor 3, servo]`
/// in PWM microseconds, the motors relative to the common throttle and
/// the servo relative to its centre: `1000 <= u_i + throttle <= 2000`
/// for the motors and `-300 <= u_4 <= 300` for the servo, so in
/// deviations `z = u - u0`:
/// `1000 - u0_i - throttle <= z_i <= 2000 - u0_i - throttle`,
/// `-300 - u0_4 <= z_4 <= 300 - u0_4`: bounds shifted by `-1` per unit of
/// the throttle parameter on the motors ([`throttle_parameter`]).
///
/// ```
/// let b = kestrel_tricopter::problems::pwm_bounds(&[15.63, 0.85, -16.01, 0.0]);
/// let at = b.at(&[1500.0]);
/// assert!((at.upper[0] - (2000.0 - 15.63 - 1500.0)).abs() < 1e-12);
/// assert_eq!(at.lower[3], -300.0);
/// ```
pub fn pwm_bounds(offsets: &[f64; 4]) -> Bounds {
    let raw_lo = [
        pwm::MOTOR_MIN,
        pwm::MOTOR_MIN,
        pwm::MOTOR_MIN,
        -pwm::SERVO_TRAVEL,
    ];
    let raw_hi = [
        pwm::MOTOR_MAX,
        pwm::MOTOR_MAX,
        pwm::MOTOR_MAX,
        pwm::SERVO_TRAVEL,
    ];
    Bounds::new(
        DVector::from_fn(4, |i, _| raw_lo[i] - offsets[i]),
        DVector::from_fn(4, |i, _| raw_hi[i] - offsets[i]),
    )
    .shifted(DMatrix::from_column_slice(4, 1, &[-1.0, -1.0, -1.0, 0.0]))
}

/// The throttle as an MPC parameter: the common motor pulse in us, over
/// the ESC range 1000-2000 us (the parameter box of `kestrel.mpqp.v1`).
pub fn throttle_parameter() -> Parameter {
    Parameter::new("throttle", pwm::MOTOR_MIN, pwm::MOTOR_MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trim_conventions_and_actuation() {
        // Thesis (7.2) relative offsets; servo given absolute.
        let t = TricopterTrim::from_u0(&[15.63, 0.85, -16.01, 1467.7]).unwrap();
        assert_eq!(t.hover_throttle, 0.0);
        assert!((t.offsets[3] - (1467.7 - 1500.0)).abs() < 1e-12);
        let a = t.actuate(&[0.0, 100.0, -2000.0, 400.0], 1500.0).unwrap();
        assert!((a.pwm[0] - 1515.63).abs() < 1e-9 && !a.saturated[0]);
        assert_eq!(a.pwm[2], 1000.0);
        assert!(a.saturated[2] && a.saturated[3]);
        assert_eq!(a.pwm[3], 1800.0);
        assert!((a.applied[2] - (1000.0 - 1500.0 + 16.01)).abs() < 1e-9);
        // Mixed conventions and bad lengths are errors.
        assert!(TricopterTrim::from_u0(&[1500.0, 0.0, 0.0, 0.0]).is_err());
        assert!(TricopterTrim::from_u0(&[0.0; 3]).is_err());
        assert!(t.actuate(&[0.0; 4], f64::NAN).is_err());
    }
}
