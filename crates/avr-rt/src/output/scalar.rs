//! [`RtScalar`]: the scalar conversions the loop needs beyond `Scalar`
//! (from `f32`, to microseconds, to and from Q15.16 bits), for `f32`
//! (integer arithmetic on the bits; one assembly routine per vector on the
//! AVR), `f64` and `kestrel_core::Fixed`.

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
