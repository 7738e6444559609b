//! [`Q16Mac`]: Q15.16 fixed point with the same values, rounding and
//! saturation as [`kestrel_core::Q16`], but with products built from four
//! 16 x 16 -> 32-bit multiplies, which the ATmega2560's hardware `MUL`
//! instructions do directly, instead of one 64 x 64-bit multiply (a library
//! call of several hundred cycles on the AVR).
//!
//! It implements [`Scalar`], so every run-time kernel generic over the
//! scalar (Kalman step, tree walk, fast gradient, the rate loop) runs on it
//! unchanged; the firmware selects it with its `fixed-mac` feature.
//!
//! With `a = ah 2^16 + al` and `b = bh 2^16 + bl` (`ah`, `bh` signed,
//! `al`, `bl` unsigned 16-bit halves):
//!
//! ```text
//! a b = ah bh 2^32 + (ah bl + al bh) 2^16 + al bl
//! round(a b / 2^16) = ah bh 2^16 + ah bl + al bh + ((al bl + 2^15) >> 16)
//! ```
//!
//! ```
//! use kestrel_avr_rt::mac::Q16Mac;
//! use kestrel_core::{Scalar, Q16};
//! let (a, b) = (1.75, -3.25);
//! let fast = Q16Mac::from_f64(a) * Q16Mac::from_f64(b);
//! let core = Q16::from_f64(a) * Q16::from_f64(b);
//! assert_eq!(fast.to_bits(), core.to_bits());
//! ```

use core::ops::{Add, AddAssign, Mul, MulAssign, Neg, Sub, SubAssign};
use kestrel_core::{Q16, Scalar};

/// Q15.16 saturating fixed point with a 16-bit-multiply MAC (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(transparent)]
pub struct Q16Mac(pub i32);

impl Q16Mac {
    /// From the raw Q15.16 bits.
    #[inline]
    pub const fn from_bits(raw: i32) -> Self {
        Q16Mac(raw)
    }
    /// The raw Q15.16 bits.
    #[inline]
    pub const fn to_bits(self) -> i32 {
        self.0
    }
}

impl From<Q16> for Q16Mac {
    fn from(q: Q16) -> Self {
        Q16Mac(q.to_bits())
    }
}

#[inline(always)]
fn split(a: i32) -> (i16, u16) {
    ((a >> 16) as i16, a as u16)
}

/// 16 x 16 -> 32 multiplies. LLVM lowers these to a 32 x 32-bit library
/// multiply on the AVR, so there they are written with the hardware
/// `MULS`/`MULSU`/`MUL` (the sequences of Atmel application note AVR201);
/// elsewhere they are plain Rust.
#[cfg(not(target_arch = "avr"))]
#[inline(always)]
fn mul_ss(a: i16, b: i16) -> i32 {
    a as i32 * b as i32
}
#[cfg(not(target_arch = "avr"))]
#[inline(always)]
fn mul_su(a: i16, b: u16) -> i32 {
    a as i32 * b as i32
}
#[cfg(not(target_arch = "avr"))]
#[inline(always)]
fn mul_uu(a: u16, b: u16) -> u32 {
    a as u32 * b as u32
}

/// One AVR201 16 x 16 -> 32 multiply: `a` in r23:r22, `b` in r21:r20, the
/// product in r19:r16. `r0`/`r1` hold the `MUL` results; `r1` (the zero
/// register) is cleared at the end.
#[cfg(target_arch = "avr")]
macro_rules! avr_mul16 {
    ($a:expr, $b:expr, $($ins:literal),+) => {{
        let a = $a;
        let b = $b;
        let (p0, p1, p2, p3): (u8, u8, u8, u8);
        // SAFETY: register-only arithmetic, see the macro documentation.
        unsafe {
            core::arch::asm!(
                "clr {z}",
                $($ins),+,
                "clr r1",
                z = out(reg) _,
                in("r22") a as u8,
                in("r23") (a >> 8) as u8,
                in("r20") b as u8,
                in("r21") (b >> 8) as u8,
                out("r16") p0,
                out("r17") p1,
                out("r18") p2,
                out("r19") p3,
                options(pure, nomem, nostack),
            );
        }
        u32::from_le_bytes([p0, p1, p2, p3])
    }};
}

#[cfg(target_arch = "avr")]
#[inline(always)]
fn mul_ss(a: i16, b: i16) -> i32 {
    avr_mul16!(
        a as u16,
        b as u16,
        "muls r23, r21",
        "movw r18, r0",
        "mul r22, r20",
        "movw r16, r0",
        "mulsu r23, r20",
        "sbc r19, {z}",
        "add r17, r0",
        "adc r18, r1",
        "adc r19, {z}",
        "mulsu r21, r22",
        "sbc r19, {z}",
        "add r17, r0",
        "adc r18, r1",
        "adc r19, {z}"
    ) as i32
}

#[cfg(target_arch = "avr")]
#[inline(always)]
fn mul_su(a: i16, b: u16) -> i32 {
    avr_mul16!(
        a as u16,
        b,
        "mulsu r23, r21",
        "movw r18, r0",
        "mul r22, r20",
        "movw r16, r0",
        "mulsu r23, r20",
        "sbc r19, {z}",
        "add r17, r0",
        "adc r18, r1",
        "adc r19, {z}",
        "mul r21, r22",
        "add r17, r0",
        "adc r18, r1",
        "adc r19, {z}"
    ) as i32
}

#[cfg(target_arch = "avr")]
#[inline(always)]
fn mul_uu(a: u16, b: u16) -> u32 {
    avr_mul16!(
        a,
        b,
        "mul r23, r21",
        "movw r18, r0",
        "mul r22, r20",
        "movw r16, r0",
        "mul r23, r20",
        "add r17, r0",
        "adc r18, r1",
        "adc r19, {z}",
        "mul r21, r22",
        "add r17, r0",
        "adc r18, r1",
        "adc r19, {z}"
    )
}

#[inline(always)]
fn sat(v: i64) -> i32 {
    if v > i32::MAX as i64 {
        i32::MAX
    } else if v < i32::MIN as i64 {
        i32::MIN
    } else {
        v as i32
    }
}

/// The exact product `a b` from four 16 x 16-bit products.
#[inline(always)]
fn product_exact(a: i32, b: i32) -> i64 {
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    ((mul_ss(ah, bh) as i64) << 32)
        + ((mul_su(ah, bl) as i64 + mul_su(bh, al) as i64) << 16)
        + mul_uu(al, bl) as i64
}

/// `round(a b / 2^16)` as an unsaturated i64.
#[inline(always)]
fn product_q16(a: i32, b: i32) -> i64 {
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let hh = mul_ss(ah, bh) as i64;
    let cross = mul_su(ah, bl) as i64 + mul_su(bh, al) as i64;
    let low = ((mul_uu(al, bl) as u64 + 0x8000) >> 16) as i64;
    (hh << 16) + cross + low
}

impl Add for Q16Mac {
    type Output = Self;
    #[inline]
    fn add(self, rhs: Self) -> Self {
        Q16Mac(self.0.saturating_add(rhs.0))
    }
}
impl Sub for Q16Mac {
    type Output = Self;
    #[inline]
    fn sub(self, rhs: Self) -> Self {
        Q16Mac(self.0.saturating_sub(rhs.0))
    }
}
impl Mul for Q16Mac {
    type Output = Self;
    #[inline]
    fn mul(self, rhs: Self) -> Self {
        Q16Mac(sat(product_q16(self.0, rhs.0)))
    }
}
impl Neg for Q16Mac {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Q16Mac(self.0.saturating_neg())
    }
}
impl AddAssign for Q16Mac {
    #[inline]
    fn add_assign(&mut self, rhs: Self) {
        *self = *self + rhs;
    }
}
impl SubAssign for Q16Mac {
    #[inline]
    fn sub_assign(&mut self, rhs: Self) {
        *self = *self - rhs;
    }
}
impl MulAssign for Q16Mac {
    #[inline]
    fn mul_assign(&mut self, rhs: Self) {
        *self = *self * rhs;
    }
}

impl Scalar for Q16Mac {
    const ZERO: Self = Q16Mac(0);
    const ONE: Self = Q16Mac(1 << 16);
    const MAX: Self = Q16Mac(i32::MAX);
    const MIN: Self = Q16Mac(i32::MIN);
    const RESOLUTION: f64 = 1.0 / 65536.0;

    #[inline]
    fn from_f64(v: f64) -> Self {
        Q16Mac(Q16::from_f64(v).to_bits())
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self.0 as f64 / 65536.0
    }
    #[inline]
    fn is_finite(self) -> bool {
        true
    }
    #[inline]
    fn mul_add(self, a: Self, b: Self) -> Self {
        self + a * b
    }
    /// Exact products summed in a saturating 64-bit accumulator and rounded
    /// once, exactly as [`Q16`]'s `dot`.
    #[inline]
    fn dot(a: &[Self], b: &[Self]) -> Self {
        let mut acc: i64 = 0;
        for (x, y) in a.iter().zip(b.iter()) {
            acc = acc.saturating_add(product_exact(x.0, y.0));
        }
        Q16Mac(sat(acc.saturating_add(0x8000) >> 16))
    }
}

impl crate::output::RtScalar for Q16Mac {
    #[inline]
    fn from_f32_fast(v: f32) -> Self {
        Q16Mac((v * 65536.0) as i32)
    }
    #[inline]
    fn to_us(self) -> Option<i32> {
        Some(((self.0 as i64 + 0x8000) >> 16) as i32)
    }
}

/// Compares [`Q16Mac`] with [`Q16`] on `n` pseudo-random products and
/// 5-element dot products (a linear congruential sequence from `seed`,
/// mixing small and full-range values); returns the number of mismatches.
/// The firmware runs it at boot, so the AVR assembly is checked on target.
pub fn self_test(seed: u32, n: u16) -> u16 {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        // Alternate full-range values with values of a few units.
        if s & 0x100 != 0 {
            s as i32
        } else {
            (s as i32) >> 12
        }
    };
    let mut bad = 0u16;
    for _ in 0..n {
        let (a, b) = (next(), next());
        if (Q16Mac(a) * Q16Mac(b)).0 != (Q16::from_bits(a) * Q16::from_bits(b)).to_bits() {
            bad += 1;
        }
        let x: [i32; 5] = core::array::from_fn(|_| next() >> 8);
        let y: [i32; 5] = core::array::from_fn(|_| next() >> 8);
        let fast = Q16Mac::dot(&x.map(Q16Mac), &y.map(Q16Mac));
        let slow = Q16::dot(&x.map(Q16::from_bits), &y.map(Q16::from_bits));
        if fast.0 != slow.to_bits() {
            bad += 1;
        }
    }
    bad
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn q(v: i32) -> Q16 {
        Q16::from_bits(v)
    }

    #[test]
    fn self_test_passes_on_the_host() {
        assert_eq!(self_test(1, 500), 0);
    }

    #[test]
    fn corner_products_match_core() {
        let corners = [
            0,
            1,
            -1,
            0x7FFF_FFFF,
            i32::MIN,
            0x8000,
            -0x8000,
            0x1_0000,
            0xFFFF,
            -0x1_0000,
            0x7FFF_0000,
        ];
        for &a in &corners {
            for &b in &corners {
                assert_eq!(
                    (Q16Mac(a) * Q16Mac(b)).0,
                    (q(a) * q(b)).to_bits(),
                    "{a} * {b}"
                );
            }
        }
    }

    proptest! {
        #[test]
        fn product_matches_core_bit_for_bit(a in any::<i32>(), b in any::<i32>()) {
            prop_assert_eq!((Q16Mac(a) * Q16Mac(b)).0, (q(a) * q(b)).to_bits());
        }

        #[test]
        fn dot_matches_core_bit_for_bit(v in proptest::collection::vec((any::<i32>(), any::<i32>()), 0..12)) {
            let a: Vec<Q16Mac> = v.iter().map(|p| Q16Mac(p.0)).collect();
            let b: Vec<Q16Mac> = v.iter().map(|p| Q16Mac(p.1)).collect();
            let ca: Vec<Q16> = v.iter().map(|p| q(p.0)).collect();
            let cb: Vec<Q16> = v.iter().map(|p| q(p.1)).collect();
            // Core saturates the wide accumulator at i64 limits along the way; with
            // at most 12 products of magnitude < 2^62 the exact sum fits i128 and
            // both agree whenever core's running sum never saturated.
            let exact: i128 = v.iter().map(|p| p.0 as i128 * p.1 as i128).sum();
            let mut run: i128 = 0;
            let mut saturated = false;
            for p in &v {
                run += p.0 as i128 * p.1 as i128;
                saturated |= run > i64::MAX as i128 || run < i64::MIN as i128;
            }
            prop_assume!(!saturated);
            let _ = exact;
            prop_assert_eq!(Q16Mac::dot(&a, &b).0, Q16::dot(&ca, &cb).to_bits());
        }

        #[test]
        fn sums_and_conversions_match_core(a in any::<i32>(), b in any::<i32>(), f in -40000.0f64..40000.0) {
            prop_assert_eq!((Q16Mac(a) + Q16Mac(b)).0, (q(a) + q(b)).to_bits());
            prop_assert_eq!((Q16Mac(a) - Q16Mac(b)).0, (q(a) - q(b)).to_bits());
            prop_assert_eq!((-Q16Mac(a)).0, (-q(a)).to_bits());
            prop_assert_eq!(Q16Mac::from_f64(f).0, Q16::from_f64(f).to_bits());
        }
    }
}
