//! The ArduCopter tricopter mixer, (3.28)-(3.29) with the corrected constants.
//!
//! Virtual inputs (roll, pitch, yaw, in microseconds of PWM) plus the common
//! throttle map to the three ESC pulses and the tail servo pulse:
//!
//! ```text
//! pwm1  = throttle                    - U_p       + offset1     (rear)
//! pwm2  = throttle + sqrt(3)/2 U_r + 1/2 U_p     + offset2     (front left)
//! pwm3  = throttle - sqrt(3)/2 U_r + 1/2 U_p     + offset3     (front right)
//! servo =                              U_y       + offset4     (tail tilt)
//! ```
//!
//! and back, (3.28): `U_r = C_r (pwm2 - pwm3)`, `U_p = C_p ((pwm2 + pwm3)/2 - pwm1)`,
//! `U_y = C_y (servo - offset4)` with `C_r = 1/sqrt(3)`, `C_p = 2/3`, `C_y = 1`
//! (the thesis's text swaps `C_r` and `C_p`; see `ERRATA.md`), and
//! `throttle = (pwm1 + pwm2 + pwm3)/3` (offsets removed first).
//!
//! Run-time code: `no_std`, allocation-free, generic over [`Scalar`].

use kestrel_core::Scalar;

/// ESC pulse range in microseconds (thesis section 3.6).
pub const ESC_PWM_RANGE: (f64, f64) = (1000.0, 2000.0);
/// Servo pulse range in microseconds (thesis section 3.6).
pub const SERVO_PWM_RANGE: (f64, f64) = (1200.0, 1800.0);

/// `C_r = 1/sqrt(3)` of (3.28).
pub const C_ROLL: f64 = 0.577_350_269_189_625_8;
/// `C_p = 2/3` of (3.28).
pub const C_PITCH: f64 = 2.0 / 3.0;
/// `C_y = 1` of (3.28).
pub const C_YAW: f64 = 1.0;
const HALF_SQRT3: f64 = 0.866_025_403_784_438_6;

/// Virtual inputs of the black-box virtual model (3.28) plus the throttle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VirtualInput<S> {
    /// Roll command `U_r` (us).
    pub roll: S,
    /// Pitch command `U_p` (us).
    pub pitch: S,
    /// Yaw command `U_y` (us of servo pulse).
    pub yaw: S,
    /// Common throttle `omega_th` (us of ESC pulse).
    pub throttle: S,
}

/// The mixer's output: saturated pulses and which of them were clipped.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MixerOutput<S> {
    /// `[pwm1, pwm2, pwm3, servo]` in microseconds, inside their ranges.
    pub pwm: [S; 4],
    /// `saturated[i]` is true when `pwm[i]` was clipped to its range.
    pub saturated: [bool; 4],
}

impl<S> MixerOutput<S> {
    /// Whether any of the four pulses was clipped.
    pub fn any_saturated(&self) -> bool {
        self.saturated.iter().any(|s| *s)
    }
}

/// The tricopter mixer (3.29) with per-output offsets and saturation.
///
/// ```
/// use kestrel_tricopter_model::{Mixer, VirtualInput};
/// let m = Mixer::<f64>::new([0.0, 0.0, 0.0, 1500.0]);
/// let v = VirtualInput { roll: 20.0, pitch: -10.0, yaw: 15.0, throttle: 1450.0 };
/// let out = m.mix(&v);
/// assert!(!out.any_saturated());
/// let back = m.unmix(&out.pwm);
/// assert!((back.roll - 20.0).abs() < 1e-12 && (back.pitch + 10.0).abs() < 1e-12);
/// assert!((back.yaw - 15.0).abs() < 1e-12 && (back.throttle - 1450.0).abs() < 1e-12);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mixer<S> {
    /// Added to `[pwm1, pwm2, pwm3, servo]` after mixing (us). The servo
    /// entry is the servo pulse at `U_y = 0` (its centre or hover trim); the
    /// motor entries are per-motor trims such as the `omega_{i,0}` of (7.2).
    pub offsets: [S; 4],
    /// Lower ends of the pulse ranges, `[esc, esc, esc, servo]`.
    pub lower: [S; 4],
    /// Upper ends of the pulse ranges.
    pub upper: [S; 4],
}

impl<S: Scalar> Mixer<S> {
    /// A mixer with the given offsets and the thesis's pulse ranges
    /// (ESC 1000-2000 us, servo 1200-1800 us).
    pub fn new(offsets: [S; 4]) -> Self {
        let (el, eu) = ESC_PWM_RANGE;
        let (sl, su) = SERVO_PWM_RANGE;
        Mixer {
            offsets,
            lower: [
                S::from_f64(el),
                S::from_f64(el),
                S::from_f64(el),
                S::from_f64(sl),
            ],
            upper: [
                S::from_f64(eu),
                S::from_f64(eu),
                S::from_f64(eu),
                S::from_f64(su),
            ],
        }
    }

    /// The unsaturated pulses for virtual inputs `v` (3.29).
    pub fn mix_unsaturated(&self, v: &VirtualInput<S>) -> [S; 4] {
        let h = S::from_f64(HALF_SQRT3);
        let half = S::from_f64(0.5);
        [
            v.throttle - v.pitch + self.offsets[0],
            v.throttle + h * v.roll + half * v.pitch + self.offsets[1],
            v.throttle - h * v.roll + half * v.pitch + self.offsets[2],
            v.yaw + self.offsets[3],
        ]
    }

    /// The pulses for virtual inputs `v`, clipped to their ranges, with the
    /// clipped ones reported.
    pub fn mix(&self, v: &VirtualInput<S>) -> MixerOutput<S> {
        let raw = self.mix_unsaturated(v);
        let mut out = MixerOutput {
            pwm: raw,
            saturated: [false; 4],
        };
        for i in 0..4 {
            let c = raw[i].clamp(self.lower[i], self.upper[i]);
            // NaN compares false both ways: report it as saturated too.
            out.saturated[i] = c != raw[i];
            out.pwm[i] = c;
        }
        out
    }

    /// The virtual inputs and throttle that produce `pwm` (3.28), the
    /// offsets removed first. Exact inverse of [`Mixer::mix_unsaturated`].
    pub fn unmix(&self, pwm: &[S; 4]) -> VirtualInput<S> {
        let p1 = pwm[0] - self.offsets[0];
        let p2 = pwm[1] - self.offsets[1];
        let p3 = pwm[2] - self.offsets[2];
        let half = S::from_f64(0.5);
        VirtualInput {
            roll: S::from_f64(C_ROLL) * (p2 - p3),
            pitch: S::from_f64(C_PITCH) * (half * (p2 + p3) - p1),
            yaw: S::from_f64(C_YAW) * (pwm[3] - self.offsets[3]),
            throttle: S::from_f64(1.0 / 3.0) * (p1 + p2 + p3),
        }
    }
}

/// `d pwm / d [U_r, U_p, U_y, throttle]`: the (constant) mixing matrix,
/// rows `[pwm1, pwm2, pwm3, servo]`. Use it to turn a PWM-input model into
/// the black-box *virtual* model (3.30): `B_v = B_pwm * M[:, 0..3]`.
pub const MIX_MATRIX: [[f64; 4]; 4] = [
    [0.0, -1.0, 0.0, 1.0],
    [HALF_SQRT3, 0.5, 0.0, 1.0],
    [-HALF_SQRT3, 0.5, 0.0, 1.0],
    [0.0, 0.0, 1.0, 0.0],
];

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::Q16;
    use proptest::prelude::*;

    #[test]
    fn constants_solve_3_29() {
        // Independent check: invert the 3x3 block of MIX_MATRIX for (roll, pitch)
        // by hand: unmix(mix(e_k)) must be e_k for each unit virtual input.
        let m = Mixer::<f64>::new([0.0; 4]);
        for k in 0..4 {
            let mut v = [0.0; 4];
            v[k] = 1.0;
            let vi = VirtualInput {
                roll: v[0],
                pitch: v[1],
                yaw: v[2],
                throttle: v[3],
            };
            let p = m.mix_unsaturated(&vi);
            for (i, row) in MIX_MATRIX.iter().enumerate() {
                assert!((p[i] - row[k]).abs() < 1e-15);
            }
            let back = m.unmix(&p);
            let got = [back.roll, back.pitch, back.yaw, back.throttle];
            for i in 0..4 {
                assert!((got[i] - v[i]).abs() < 1e-15, "{k} {i} {got:?}");
            }
        }
        assert!((C_ROLL * C_ROLL * 3.0 - 1.0).abs() < 1e-15);
    }

    #[test]
    fn saturation_is_reported() {
        let m = Mixer::<f64>::new([0.0, 0.0, 0.0, 1500.0]);
        let out = m.mix(&VirtualInput {
            roll: 0.0,
            pitch: 300.0,
            yaw: 400.0,
            throttle: 1900.0,
        });
        assert_eq!(out.pwm, [1600.0, 2000.0, 2000.0, 1800.0]);
        assert_eq!(out.saturated, [false, true, true, true]);
        let low = m.mix(&VirtualInput {
            throttle: 900.0,
            ..Default::default()
        });
        assert_eq!(low.pwm[0], 1000.0);
        assert!(low.saturated[0] && !low.saturated[3]);
        let nan = m.mix(&VirtualInput {
            roll: f64::NAN,
            ..Default::default()
        });
        assert!(nan.saturated[1] && nan.saturated[2]);
    }

    #[test]
    fn fixed_point_matches_f64() {
        let mf = Mixer::<f64>::new([3.0, -2.0, 1.0, 1480.0]);
        let mq = Mixer::<Q16>::new([3.0, -2.0, 1.0, 1480.0].map(Q16::from_f64));
        let v = VirtualInput {
            roll: 30.0,
            pitch: -12.5,
            yaw: 40.0,
            throttle: 1500.0,
        };
        let vq = VirtualInput {
            roll: Q16::from_f64(v.roll),
            pitch: Q16::from_f64(v.pitch),
            yaw: Q16::from_f64(v.yaw),
            throttle: Q16::from_f64(v.throttle),
        };
        let a = mf.mix(&v);
        let b = mq.mix(&vq);
        for i in 0..4 {
            assert!((a.pwm[i] - b.pwm[i].to_f64()).abs() < 1e-3);
        }
    }

    proptest! {
        #[test]
        fn unmix_inverts_mix(r in -300.0f64..300.0, p in -300.0f64..300.0, y in -300.0f64..300.0,
                             t in 1000.0f64..2000.0, o in proptest::array::uniform4(-50.0f64..50.0)) {
            let m = Mixer::<f64>::new(o);
            let v = VirtualInput { roll: r, pitch: p, yaw: y, throttle: t };
            let back = m.unmix(&m.mix_unsaturated(&v));
            prop_assert!((back.roll - r).abs() < 1e-9);
            prop_assert!((back.pitch - p).abs() < 1e-9);
            prop_assert!((back.yaw - y).abs() < 1e-9);
            prop_assert!((back.throttle - t).abs() < 1e-9);
            let out = m.mix(&v);
            for i in 0..4 {
                prop_assert!(out.pwm[i] >= m.lower[i] && out.pwm[i] <= m.upper[i]);
                prop_assert_eq!(out.saturated[i], out.pwm[i] != m.mix_unsaturated(&v)[i]);
            }
        }
    }
}
