//! [`Q16Mac`]'s arithmetic: the operators (saturating, products rounded
//! as `kestrel_core::Q16`), [`Scalar`] and [`RtScalar`].

use super::dot_wide::dot_wide;
use super::mul_wide::mul_wide;
use super::q16mac::Q16Mac;
use crate::output::RtScalar;
use core::ops::{Add, AddAssign, Mul, MulAssign, Neg, Sub, SubAssign};
use kestrel_core::{Q16, Scalar};

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

/// `round(a b / 2^16)` as an unsaturated i64 (|a b| < 2^62, no overflow).
#[inline(always)]
fn product_q16(a: i32, b: i32) -> i64 {
    (mul_wide(a, b) + 0x8000) >> 16
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
    /// Exact products summed and rounded once, as [`Q16`]'s `dot`. On the
    /// AVR the whole loop is one assembly kernel (`dot_wide_avr`) with a
    /// 72-bit accumulator, so it equals `Q16` whenever `Q16`'s 64-bit running
    /// sum does not saturate midway (it would take products near 2^62).
    #[inline]
    fn dot(a: &[Self], b: &[Self]) -> Self {
        Q16Mac(sat(dot_wide(a, b).saturating_add(0x8000) >> 16))
    }
}

impl RtScalar for Q16Mac {
    #[inline]
    fn from_f32_fast(v: f32) -> Self {
        Q16Mac((v * 65536.0) as i32)
    }
    #[inline]
    fn to_us(self) -> Option<i32> {
        Some(((self.0 as i64 + 0x8000) >> 16) as i32)
    }
    #[inline]
    fn to_q16(self) -> Option<i32> {
        Some(self.0)
    }
    #[inline]
    fn from_q16(bits: i32) -> Self {
        Q16Mac(bits)
    }
    #[inline]
    fn as_q16_bits(v: &[Self]) -> Option<&[i32]> {
        // SAFETY: `Q16Mac` is `#[repr(transparent)]` over its Q15.16 bits,
        // so a slice of it has the layout of an `i32` slice of the same length.
        Some(unsafe { core::slice::from_raw_parts(v.as_ptr() as *const i32, v.len()) })
    }
    #[inline]
    fn from_q16_bits(bits: &[i32]) -> Option<&[Self]> {
        // SAFETY: as in `as_q16_bits`, the other way round.
        Some(unsafe { core::slice::from_raw_parts(bits.as_ptr() as *const Self, bits.len()) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::Q16;
    use proptest::prelude::*;

    fn q(v: i32) -> Q16 {
        Q16::from_bits(v)
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
