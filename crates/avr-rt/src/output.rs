//! Output limits, saturation and the failsafe.
//!
//! # The failsafe
//!
//! Once per control period [`Failsafe::on_tick`] is told whether a fresh,
//! valid command frame arrived since the previous tick:
//!
//! - a valid command with finite values: run the controller (after a failsafe
//!   the loop is told to restart its estimator and integrators: *recovery*);
//! - no valid frame this period, the first time: hold the previous outputs;
//! - no valid frame for **two** periods in a row (dropped or corrupted
//!   frames), or any **non-finite** value (in the command or in the
//!   controller's result): output the [`SafeOutput`] (by default motors at
//!   1000 us, i.e. stopped, and the servo centred at 1500 us) until a valid
//!   frame comes.
//!
//! Whatever happens, [`PwmLimits::saturate`] keeps the ESC pulses within
//! 1000-2000 us and the servo pulse within 1200-1800 us (thesis section 2.1.2).

use kestrel_core::{Fixed, Scalar};

/// The scalar conversions the run-time loop needs beyond [`Scalar`], done
/// without double-precision arithmetic (which the AVR would emulate slowly).
pub trait RtScalar: Scalar {
    /// Converts from `f32` (fixed point saturates, NaN becomes zero).
    fn from_f32_fast(v: f32) -> Self;
    /// Rounds to the nearest integer microsecond; `None` if not finite.
    fn to_us(self) -> Option<i32>;
    /// The nearest Q15.16 value as raw bits (saturated); `None` if not finite.
    fn to_q16(self) -> Option<i32>;
    /// From Q15.16 raw bits.
    fn from_q16(bits: i32) -> Self;
    /// The values as their Q15.16 raw bits without a copy, for scalars
    /// stored as exactly those bits (`Q16Mac`, `Q16`); `None` (the
    /// default) for every other scalar, which converts with
    /// [`RtScalar::to_q16`].
    #[inline]
    fn as_q16_bits(v: &[Self]) -> Option<&[i32]> {
        let _ = v;
        None
    }
    /// Q15.16 raw bits seen as values without a copy (the inverse of
    /// [`RtScalar::as_q16_bits`]); `None` (the default) where `Self` is
    /// not stored as those bits.
    #[inline]
    fn from_q16_bits(bits: &[i32]) -> Option<&[Self]> {
        let _ = bits;
        None
    }
    /// Every value's [`RtScalar::to_q16`] into `out` (as many as the
    /// shorter of the two holds); `None` if one is not finite (`out` is
    /// then partly written). For `f32` on the AVR one assembly routine
    /// for all values (checked against `to_q16` on the target at boot by
    /// `mac::self_test`).
    #[inline]
    fn to_q16_all(v: &[Self], out: &mut [i32]) -> Option<()> {
        for (o, x) in out.iter_mut().zip(v) {
            *o = x.to_q16()?;
        }
        Some(())
    }
    /// The values' IEEE single-precision bit patterns (as `i32` words)
    /// without a copy, for `f32`; `None` (the default) for every other
    /// scalar. Lets the explicit MPC's assembly convert `f32` parameters
    /// itself, exactly as [`RtScalar::to_q16`] does.
    #[inline]
    fn as_f32_bits(v: &[Self]) -> Option<&[i32]> {
        let _ = v;
        None
    }
}

/// `2^16` as f32 bits' exponent step.
const EXP16: u32 = 16 << 23;

impl RtScalar for f32 {
    #[inline]
    fn from_f32_fast(v: f32) -> Self {
        v
    }
    /// Integer arithmetic on the bits, no float routine: the mantissa
    /// shifted by `exponent - 134`, rounded half away from zero (exact),
    /// saturated from `|v| >= 2^15`.
    #[inline]
    fn to_q16(self) -> Option<i32> {
        let bits = self.to_bits();
        let exp = ((bits >> 23) & 0xFF) as i16;
        if exp == 0xFF {
            return None;
        }
        // v * 2^16 = m * 2^(exp - 134) with m in [2^23, 2^24).
        let k = exp - 134;
        if k <= -25 {
            return Some(0); // below half the resolution (and subnormals)
        }
        let neg = bits >> 31 != 0;
        if k >= 8 {
            return Some(if neg { i32::MIN } else { i32::MAX });
        }
        let m = (bits & 0x7F_FFFF) | 0x80_0000;
        let q = if k >= 0 {
            (m << k) as i32
        } else {
            // round(m / 2^s) = (floor(m / 2^(s - 1)) + 1) / 2, the shift by
            // whole bytes then bits (the AVR has no barrel shifter: LLVM
            // shifts one bit per pass, and `1 << (s - 1)` is another loop).
            let s = (-k) as u8; // 1..=24
            (crate::shift::shr_var(m as i32, s - 1) + 1) >> 1
        }; // < 2^31
        Some(if neg { -q } else { q })
    }
    #[inline]
    fn to_q16_all(v: &[Self], out: &mut [i32]) -> Option<()> {
        let n = v.len().min(out.len());
        #[cfg(target_arch = "avr")]
        if n <= 255 {
            // SAFETY: `v` holds at least `n` values to read, `out` at
            // least `n` to write.
            let ok = unsafe { f32_to_q16_avr(v.as_ptr(), out.as_mut_ptr(), n as u8) };
            return ok.then_some(());
        }
        for (o, x) in out.iter_mut().zip(v).take(n) {
            *o = x.to_q16()?;
        }
        Some(())
    }
    #[inline]
    fn as_f32_bits(v: &[Self]) -> Option<&[i32]> {
        // SAFETY: `f32` and `i32` have the same size and alignment and
        // every bit pattern is a valid `i32`: a slice of one has the
        // layout of a slice of the other of the same length.
        Some(unsafe { core::slice::from_raw_parts(v.as_ptr() as *const i32, v.len()) })
    }
    /// avr-libc's conversion, then scales by `2^-16` through the exponent.
    #[inline]
    fn from_q16(bits: i32) -> Self {
        if bits == 0 {
            return 0.0;
        }
        f32::from_bits((bits as f32).to_bits() - EXP16)
    }
    #[inline]
    fn to_us(self) -> Option<i32> {
        if !self.is_finite() {
            return None;
        }
        let c = self.clamp(-1.0e9, 1.0e9);
        Some(if c >= 0.0 {
            (c + 0.5) as i32
        } else {
            (c - 0.5) as i32
        })
    }
}

/// `n` values of [`RtScalar::to_q16`] for `f32` in one assembly routine
/// (the AVR has no barrel shifter; the Rust form's shifts and saturation
/// cost about twice as much): per value the assembly text `f32_to_q16!`
/// (`src/avr_asm.rs`: exponent and mantissa in registers, saturation,
/// rounding shift, sign), the same text as the explicit MPC's
/// quantisation of `f32` parameters (`explicit/tree16/walk_avr.rs`); a value
/// that is not finite stops the conversion with `false`.
///
/// # Safety
/// `src` must hold `n` readable values and `dst` `n` writable ones.
#[cfg(target_arch = "avr")]
#[inline(never)]
#[allow(named_asm_labels)] // one copy: the function is never inlined
unsafe fn f32_to_q16_avr(src: *const f32, dst: *mut i32, n: u8) -> bool {
    if n == 0 {
        return true;
    }
    let status: u8;
    // SAFETY: the caller's contract; r2 is saved by the compiler (declared
    // clobbered) and used as a zero register.
    unsafe {
        core::arch::asm!(
            "clr r2",
            ".Lkf_val:",
            "ld r16, X+",
            "ld r17, X+",
            "ld r18, X+",
            "ld r19, X+",
            f32_to_q16!(".Lkf_", "q", "r20", "r22", ".Lkf_nonfinite"),
            "st Z+, r16",
            "st Z+, r17",
            "st Z+, r18",
            "st Z+, r19",
            "dec r24",
            "breq .Lkf_ok",
            "rjmp .Lkf_val",
            ".Lkf_ok:",
            "ldi r24, 1",
            "rjmp .Lkf_end",
            ".Lkf_nonfinite:",
            "clr r24",
            ".Lkf_end:",
            inout("X") src => _,
            inout("Z") dst => _,
            inout("r24") n => status,
            out("r2") _, out("r16") _, out("r17") _, out("r18") _, out("r19") _,
            out("r20") _, out("r21") _, out("r22") _,
        );
    }
    status != 0
}

impl RtScalar for f64 {
    #[inline]
    fn from_f32_fast(v: f32) -> Self {
        v as f64
    }
    #[inline]
    fn to_q16(self) -> Option<i32> {
        if !self.is_finite() {
            return None;
        }
        let s = self * 65536.0;
        Some(if s >= 0.0 { s + 0.5 } else { s - 0.5 } as i32)
    }
    #[inline]
    fn from_q16(bits: i32) -> Self {
        bits as f64 / 65536.0
    }
    #[inline]
    fn to_us(self) -> Option<i32> {
        if !self.is_finite() {
            return None;
        }
        let c = self.clamp(-1.0e9, 1.0e9);
        Some(if c >= 0.0 {
            (c + 0.5) as i32
        } else {
            (c - 0.5) as i32
        })
    }
}

impl<const FRAC: u32> RtScalar for Fixed<FRAC> {
    #[inline]
    fn from_f32_fast(v: f32) -> Self {
        // Scaling by a power of two is exact; `as` saturates and maps NaN to 0.
        Fixed((v * (1u32 << FRAC) as f32) as i32)
    }
    #[inline]
    fn to_us(self) -> Option<i32> {
        let half = 1i64 << (FRAC - 1);
        Some(((self.0 as i64 + half) >> FRAC) as i32)
    }
    #[inline]
    fn to_q16(self) -> Option<i32> {
        let v = self.0 as i64;
        let q = if FRAC >= 16 {
            let s = FRAC - 16;
            if s == 0 { v } else { (v + (1 << (s - 1))) >> s }
        } else {
            v << (16 - FRAC)
        };
        Some(q.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
    }
    #[inline]
    fn as_q16_bits(v: &[Self]) -> Option<&[i32]> {
        if FRAC != 16 {
            return None;
        }
        // SAFETY: `Fixed` is `#[repr(transparent)]` over `i32`, so a slice
        // of it has the layout of an `i32` slice of the same length; with
        // 16 fraction bits the raw value is the Q15.16 value.
        Some(unsafe { core::slice::from_raw_parts(v.as_ptr() as *const i32, v.len()) })
    }
    #[inline]
    fn from_q16_bits(bits: &[i32]) -> Option<&[Self]> {
        if FRAC != 16 {
            return None;
        }
        // SAFETY: as in `as_q16_bits`, the other way round.
        Some(unsafe { core::slice::from_raw_parts(bits.as_ptr() as *const Self, bits.len()) })
    }
    #[inline]
    fn from_q16(bits: i32) -> Self {
        let v = bits as i64;
        let f = if FRAC >= 16 {
            v << (FRAC - 16)
        } else {
            let s = 16 - FRAC;
            (v + (1 << (s - 1))) >> s
        };
        Fixed(f.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
    }
}

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
    /// the failsafe).
    pub fn saturate<S: RtScalar>(&self, pwm: &[S; 4]) -> Option<[u16; 4]> {
        let mut out = [0u16; 4];
        for (i, (o, v)) in out.iter_mut().zip(pwm).enumerate() {
            let us = v.to_us()?;
            let (lo, hi) = if i < 3 {
                (self.esc_min, self.esc_max)
            } else {
                (self.servo_min, self.servo_max)
            };
            *o = us.clamp(lo as i32, hi as i32) as u16;
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
    /// still cannot leave them).
    pub fn pwm(&self, limits: &PwmLimits) -> [u16; 4] {
        let e = self.esc.clamp(limits.esc_min, limits.esc_max);
        [
            e,
            e,
            e,
            self.servo.clamp(limits.servo_min, limits.servo_max),
        ]
    }
}

/// What the loop does this period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    /// Run the controller; `recovered` is true on the first period after a failsafe.
    Run {
        /// Restart estimator and integrators before running.
        recovered: bool,
    },
    /// Hold the previous outputs (one missing frame).
    Hold,
    /// Output the safe pulses.
    Safe,
}

/// Why the failsafe is active.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FailsafeReason {
    /// No valid frame for [`Failsafe::TIMEOUT_PERIODS`] periods.
    Timeout,
    /// A non-finite value in the command or the controller output.
    NonFinite,
}

/// The failsafe state machine (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Failsafe {
    missed: u8,
    active: Option<FailsafeReason>,
    started: bool,
    /// How many times the failsafe was entered.
    pub entries: u16,
}

impl Default for Failsafe {
    fn default() -> Self {
        Self::new()
    }
}

impl Failsafe {
    /// Periods without a valid frame after which the safe output is held.
    pub const TIMEOUT_PERIODS: u8 = 2;

    /// A failsafe that is active until the first valid command arrives.
    pub const fn new() -> Self {
        Failsafe {
            missed: 0,
            active: Some(FailsafeReason::Timeout),
            started: false,
            entries: 0,
        }
    }

    /// The reason the failsafe is active, if it is.
    pub fn active(&self) -> Option<FailsafeReason> {
        self.active
    }

    fn enter(&mut self, why: FailsafeReason) {
        if self.active.is_none() {
            self.entries = self.entries.wrapping_add(1);
        }
        self.active = Some(why);
    }

    /// Decides this period's action. `fresh` is `Some(finite)` if a new valid
    /// frame arrived since the last tick (`finite` tells whether all its values are finite).
    pub fn on_tick(&mut self, fresh: Option<bool>) -> Decision {
        match fresh {
            Some(true) => {
                self.missed = 0;
                let recovered = self.active.is_some() && self.started;
                self.started = true;
                self.active = None;
                Decision::Run { recovered }
            }
            Some(false) => {
                self.missed = 0;
                self.enter(FailsafeReason::NonFinite);
                Decision::Safe
            }
            None => {
                self.missed = self.missed.saturating_add(1);
                if self.missed >= Self::TIMEOUT_PERIODS {
                    self.enter(FailsafeReason::Timeout);
                }
                if self.active.is_some() {
                    Decision::Safe
                } else {
                    Decision::Hold
                }
            }
        }
    }

    /// Reports a non-finite controller output in a period that ran: the
    /// failsafe becomes active at once.
    pub fn non_finite_output(&mut self) {
        self.enter(FailsafeReason::NonFinite);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::Q16;
    use proptest::prelude::*;

    #[test]
    fn failsafe_sequence() {
        let mut f = Failsafe::new();
        assert_eq!(f.on_tick(None), Decision::Safe); // nothing received yet
        assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: false });
        assert_eq!(f.on_tick(None), Decision::Hold); // one frame lost: hold
        assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: false });
        assert_eq!(f.on_tick(None), Decision::Hold);
        assert_eq!(f.on_tick(None), Decision::Safe); // two periods: failsafe
        assert_eq!(f.active(), Some(FailsafeReason::Timeout));
        assert_eq!(f.on_tick(None), Decision::Safe);
        assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: true });
        assert_eq!(f.active(), None);
        assert_eq!(f.on_tick(Some(false)), Decision::Safe); // NaN in the frame
        assert_eq!(f.active(), Some(FailsafeReason::NonFinite));
        assert_eq!(f.on_tick(None), Decision::Safe);
        assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: true });
        f.non_finite_output();
        assert_eq!(f.active(), Some(FailsafeReason::NonFinite));
        assert_eq!(f.entries, 3);
    }

    #[test]
    fn non_finite_output_is_refused() {
        let l = PwmLimits::default();
        assert_eq!(l.saturate(&[1500.0f32, f32::NAN, 1500.0, 1500.0]), None);
        assert_eq!(l.saturate(&[f64::INFINITY, 0.0, 0.0, 0.0]), None);
        assert_eq!(
            l.saturate(&[1500.4f32, 999.0, 2600.0, 1100.0]),
            Some([1500, 1000, 2000, 1200])
        );
    }

    #[test]
    fn fixed_conversions() {
        assert_eq!(Q16::from_f32_fast(1.5), Q16::from_f64(1.5));
        assert_eq!(Q16::from_f32_fast(f32::NAN), Q16::ZERO);
        assert_eq!(Q16::from_f32_fast(1e9), Q16::MAX);
        assert_eq!(Q16::from_f64(1499.5).to_us(), Some(1500));
        assert_eq!(Q16::from_f64(-2.6).to_us(), Some(-3));
    }

    #[test]
    fn safe_output_is_clamped() {
        let l = PwmLimits::default();
        assert_eq!(SafeOutput::default().pwm(&l), [1000, 1000, 1000, 1500]);
        let odd = SafeOutput {
            esc: 0,
            servo: 5000,
        };
        assert_eq!(odd.pwm(&l), [1000, 1000, 1000, 1800]);
    }

    proptest! {
        #[test]
        fn saturated_pwm_never_leaves_limits(v in proptest::array::uniform4(-1e7f32..1e7)) {
            let l = PwmLimits::default();
            let p = l.saturate(&v).unwrap();
            for (i, w) in p.iter().enumerate() {
                if i < 3 { prop_assert!((1000..=2000).contains(w)); }
                else { prop_assert!((1200..=1800).contains(w)); }
            }
            let q = l.saturate(&v.map(|x| Q16::from_f64(x as f64))).unwrap();
            for (i, w) in q.iter().enumerate() {
                if i < 3 { prop_assert!((1000..=2000).contains(w)); }
                else { prop_assert!((1200..=1800).contains(w)); }
            }
        }

        #[test]
        fn saturate_matches_clamped_round(v in -3000.0f64..3000.0) {
            let l = PwmLimits::default();
            let p = l.saturate(&[v, v, v, v]).unwrap();
            prop_assert_eq!(p[0] as f64, v.round().clamp(1000.0, 2000.0));
            prop_assert_eq!(p[3] as f64, v.round().clamp(1200.0, 1800.0));
        }
    }

    #[test]
    fn q16_conversions_handle_the_edges() {
        assert_eq!(f32::NAN.to_q16(), None);
        assert_eq!(f64::INFINITY.to_q16(), None);
        assert_eq!(1.0e6f32.to_q16(), Some(i32::MAX));
        assert_eq!((-1.0e6f32).to_q16(), Some(i32::MIN));
        assert_eq!(1.0e-30f32.to_q16(), Some(0));
        assert_eq!(<f32 as RtScalar>::from_q16(0), 0.0);
        assert_eq!(<f32 as RtScalar>::from_q16(-65536), -1.0);
        assert_eq!(Q16::from_f64(1.5).to_q16(), Some(98304));
        assert_eq!(<Fixed<8> as RtScalar>::from_q16(98304).0, 384);
        assert_eq!(Fixed::<20>(3 << 20).to_q16(), Some(3 << 16));
    }

    /// The f32 conversion is exact: `round(v 2^16)`, ties away from zero,
    /// saturated (computed in f64, where `v 2^16` is exact).
    fn f32_q16_reference(f: f32) -> i32 {
        let s = f as f64 * 65536.0;
        s.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32
    }

    #[test]
    fn f32_to_q16_edges() {
        for f in [
            0.0f32,
            -0.0,
            0.5 / 65536.0,
            -0.5 / 65536.0,
            1.5 / 65536.0,
            -2.5 / 65536.0,
            0.49 / 65536.0,
            f32::MIN_POSITIVE,
            1.0e-40,
            1.0,
            -1.0,
            32767.998,
            32768.0,
            -32768.0,
            f32::MAX,
            f32::MIN,
        ] {
            assert_eq!(f.to_q16(), Some(f32_q16_reference(f)), "{f:e}");
        }
        assert_eq!(f32::INFINITY.to_q16(), None);
        assert_eq!(f32::NEG_INFINITY.to_q16(), None);
    }

    proptest! {
        #[test]
        fn to_q16_all_is_to_q16_of_each(bits in proptest::array::uniform4(proptest::num::u32::ANY)) {
            let v = bits.map(f32::from_bits);
            let mut all = [0i32; 4];
            let got = <f32 as RtScalar>::to_q16_all(&v, &mut all);
            let each: Option<Vec<i32>> = v.iter().map(|x| x.to_q16()).collect();
            prop_assert_eq!(got.is_some(), each.is_some());
            if let Some(each) = each {
                prop_assert_eq!(&all[..], &each[..]);
            }
            // As many as the shorter slice holds.
            let mut two = [0i32; 2];
            let _ = <f32 as RtScalar>::to_q16_all(&v, &mut two);
            let mut five = [7i32; 5];
            let _ = <f32 as RtScalar>::to_q16_all(&v, &mut five);
            prop_assert_eq!(five[4], 7);
        }

        #[test]
        fn f32_to_q16_is_exact(bits in proptest::num::u32::ANY) {
            let f = f32::from_bits(bits);
            prop_assume!(f.is_finite());
            prop_assert_eq!(f.to_q16(), Some(f32_q16_reference(f)));
        }

        #[test]
        fn q16_conversions_round_to_nearest(v in -32000.0f64..32000.0) {
            let exact = (v * 65536.0).round();
            let f = v as f32;
            let from_f32 = f.to_q16().unwrap() as f64;
            prop_assert!((from_f32 - (f as f64 * 65536.0).round()).abs() <= 1.0);
            prop_assert!((v.to_q16().unwrap() as f64 - exact).abs() <= 0.5 + 1e-9);
            let back = <f32 as RtScalar>::from_q16(exact as i32) as f64;
            prop_assert!((back - exact / 65536.0).abs() <= 1e-7 * v.abs().max(1.0));
        }
    }
}
