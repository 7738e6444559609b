//! [`Q16Mac`]: Q15.16 fixed point with the same values, rounding and
//! saturation as [`kestrel_core::Q16`], whose 32 x 32 -> 64-bit products are
//! written with the ATmega2560's hardware `MUL` (16 byte products in inline
//! assembly) instead of LLVM's generic 64 x 64-bit multiply.
//!
//! It implements [`Scalar`], so every run-time kernel generic over the
//! scalar (Kalman step, tree walk, fast gradient, the rate loop) runs on it
//! unchanged; the firmware selects it with its `fixed-mac` feature, and
//! checks it against `Q16` on the target at boot ([`self_test`]).
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

/// The exact 64-bit product of two 32-bit integers. LLVM lowers
/// `a as i64 * b as i64` to a generic 64 x 64-bit multiply on the AVR (a
/// library call of several hundred cycles), so there it is written out:
/// the 16 byte products of the unsigned operands with the hardware `MUL`,
/// accumulated into 8 bytes, then the two signed corrections
/// (`- 2^32 b` if `a < 0`, `- 2^32 a` if `b < 0`). Elsewhere it is plain Rust.
#[cfg(not(target_arch = "avr"))]
#[inline(always)]
fn mul_wide(a: i32, b: i32) -> i64 {
    a as i64 * b as i64
}

#[cfg(target_arch = "avr")]
#[inline(always)]
fn mul_wide(a: i32, b: i32) -> i64 {
    let [a0, a1, a2, a3] = a.to_le_bytes();
    let [b0, b1, b2, b3] = b.to_le_bytes();
    let (p0, p1, p2, p3, p4, p5, p6, p7): (u8, u8, u8, u8, u8, u8, u8, u8);
    // SAFETY: register-only arithmetic; r0/r1 receive the MUL results and
    // r1 (the zero register) is cleared at the end.
    unsafe {
        core::arch::asm!(
                "clr {p0}",
                "clr {p1}",
                "clr {p2}",
                "clr {p3}",
                "clr {p4}",
                "clr {p5}",
                "clr {p6}",
                "clr {p7}",
                "clr {z}",
                "mul r22, r18",
                "add {p0}, r0",
                "adc {p1}, r1",
                "adc {p2}, {z}",
                "adc {p3}, {z}",
                "adc {p4}, {z}",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r22, r19",
                "add {p1}, r0",
                "adc {p2}, r1",
                "adc {p3}, {z}",
                "adc {p4}, {z}",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r22, r20",
                "add {p2}, r0",
                "adc {p3}, r1",
                "adc {p4}, {z}",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r22, r21",
                "add {p3}, r0",
                "adc {p4}, r1",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r23, r18",
                "add {p1}, r0",
                "adc {p2}, r1",
                "adc {p3}, {z}",
                "adc {p4}, {z}",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r23, r19",
                "add {p2}, r0",
                "adc {p3}, r1",
                "adc {p4}, {z}",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r23, r20",
                "add {p3}, r0",
                "adc {p4}, r1",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r23, r21",
                "add {p4}, r0",
                "adc {p5}, r1",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r24, r18",
                "add {p2}, r0",
                "adc {p3}, r1",
                "adc {p4}, {z}",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r24, r19",
                "add {p3}, r0",
                "adc {p4}, r1",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r24, r20",
                "add {p4}, r0",
                "adc {p5}, r1",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r24, r21",
                "add {p5}, r0",
                "adc {p6}, r1",
                "adc {p7}, {z}",
                "mul r25, r18",
                "add {p3}, r0",
                "adc {p4}, r1",
                "adc {p5}, {z}",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r25, r19",
                "add {p4}, r0",
                "adc {p5}, r1",
                "adc {p6}, {z}",
                "adc {p7}, {z}",
                "mul r25, r20",
                "add {p5}, r0",
                "adc {p6}, r1",
                "adc {p7}, {z}",
                "mul r25, r21",
                "add {p6}, r0",
                "adc {p7}, r1",
                "sbrs r25, 7",
                "rjmp 1f",
                "sub {p4}, r18",
                "sbc {p5}, r19",
                "sbc {p6}, r20",
                "sbc {p7}, r21",
                "1:",
                "sbrs r21, 7",
                "rjmp 2f",
                "sub {p4}, r22",
                "sbc {p5}, r23",
                "sbc {p6}, r24",
                "sbc {p7}, r25",
                "2:",
                "clr r1",
            p0 = out(reg) p0,
            p1 = out(reg) p1,
            p2 = out(reg) p2,
            p3 = out(reg) p3,
            p4 = out(reg) p4,
            p5 = out(reg) p5,
            p6 = out(reg) p6,
            p7 = out(reg) p7,
            z = out(reg) _,
            in("r22") a0,
            in("r23") a1,
            in("r24") a2,
            in("r25") a3,
            in("r18") b0,
            in("r19") b1,
            in("r20") b2,
            in("r21") b3,
            options(pure, nomem, nostack),
        );
    }
    i64::from_le_bytes([p0, p1, p2, p3, p4, p5, p6, p7])
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
    /// AVR the whole loop is one assembly kernel ([`dot_wide_avr`]) with a
    /// 72-bit accumulator, so it equals `Q16` whenever `Q16`'s 64-bit running
    /// sum does not saturate midway (it would take products near 2^62).
    #[inline]
    fn dot(a: &[Self], b: &[Self]) -> Self {
        Q16Mac(sat(dot_wide(a, b).saturating_add(0x8000) >> 16))
    }
}

/// The exact sum of products, saturated to i64.
#[cfg(not(target_arch = "avr"))]
#[inline(always)]
fn dot_wide(a: &[Q16Mac], b: &[Q16Mac]) -> i64 {
    let mut acc: i64 = 0;
    for (x, y) in a.iter().zip(b.iter()) {
        acc = acc.saturating_add(mul_wide(x.0, y.0));
    }
    acc
}

#[cfg(target_arch = "avr")]
#[inline(always)]
fn dot_wide(a: &[Q16Mac], b: &[Q16Mac]) -> i64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0;
    }
    if n > 255 {
        let mut acc: i64 = 0;
        for (x, y) in a.iter().zip(b.iter()) {
            acc = acc.saturating_add(mul_wide(x.0, y.0));
        }
        return acc;
    }
    // SAFETY: both slices hold at least `n` (1..=255) elements.
    unsafe { dot_wide_avr(a.as_ptr(), b.as_ptr(), n as u8) }
}

/// `sum a[i] b[i]` over `n` pairs in a 72-bit accumulator (byte products
/// of the unsigned operands with `MUL`, then the signed corrections
/// `- 2^32 b [a < 0] - 2^32 a [b < 0] + 2^64 [a < 0 and b < 0]`), saturated
/// to i64.
///
/// # Safety
/// `a` and `b` must point to at least `n >= 1` readable elements.
#[cfg(target_arch = "avr")]
#[inline(never)]
unsafe fn dot_wide_avr(a: *const Q16Mac, b: *const Q16Mac, n: u8) -> i64 {
    let (c0, c1, c2, c3, c4, c5, c6, c7, c8): (u8, u8, u8, u8, u8, u8, u8, u8, u8);
    // SAFETY: reads 4 n bytes from each pointer (the caller's contract);
    // r0/r1 receive the MUL results and r1 is cleared at the end.
    unsafe {
        core::arch::asm!(
                "clr {c0}",
                "clr {c1}",
                "clr {c2}",
                "clr {c3}",
                "clr {c4}",
                "clr {c5}",
                "clr {c6}",
                "clr {c7}",
                "clr {c8}",
                "clr {z}",
                "1:",
                "ld r22, X+",
                "ld r23, X+",
                "ld r24, X+",
                "ld r25, X+",
                "ld r18, Z+",
                "ld r19, Z+",
                "ld r20, Z+",
                "ld r21, Z+",
                "mul r22, r18",
                "add {c0}, r0",
                "adc {c1}, r1",
                "adc {c2}, {z}",
                "adc {c3}, {z}",
                "adc {c4}, {z}",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r22, r19",
                "add {c1}, r0",
                "adc {c2}, r1",
                "adc {c3}, {z}",
                "adc {c4}, {z}",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r22, r20",
                "add {c2}, r0",
                "adc {c3}, r1",
                "adc {c4}, {z}",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r22, r21",
                "add {c3}, r0",
                "adc {c4}, r1",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r23, r18",
                "add {c1}, r0",
                "adc {c2}, r1",
                "adc {c3}, {z}",
                "adc {c4}, {z}",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r23, r19",
                "add {c2}, r0",
                "adc {c3}, r1",
                "adc {c4}, {z}",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r23, r20",
                "add {c3}, r0",
                "adc {c4}, r1",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r23, r21",
                "add {c4}, r0",
                "adc {c5}, r1",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r24, r18",
                "add {c2}, r0",
                "adc {c3}, r1",
                "adc {c4}, {z}",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r24, r19",
                "add {c3}, r0",
                "adc {c4}, r1",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r24, r20",
                "add {c4}, r0",
                "adc {c5}, r1",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r24, r21",
                "add {c5}, r0",
                "adc {c6}, r1",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r25, r18",
                "add {c3}, r0",
                "adc {c4}, r1",
                "adc {c5}, {z}",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r25, r19",
                "add {c4}, r0",
                "adc {c5}, r1",
                "adc {c6}, {z}",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r25, r20",
                "add {c5}, r0",
                "adc {c6}, r1",
                "adc {c7}, {z}",
                "adc {c8}, {z}",
                "mul r25, r21",
                "add {c6}, r0",
                "adc {c7}, r1",
                "adc {c8}, {z}",
                "sbrs r25, 7",
                "rjmp 2f",
                "sub {c4}, r18",
                "sbc {c5}, r19",
                "sbc {c6}, r20",
                "sbc {c7}, r21",
                "sbc {c8}, {z}",
                "sbrc r21, 7",
                "inc {c8}",
                "2:",
                "sbrs r21, 7",
                "rjmp 3f",
                "sub {c4}, r22",
                "sbc {c5}, r23",
                "sbc {c6}, r24",
                "sbc {c7}, r25",
                "sbc {c8}, {z}",
                "3:",
                "dec {n}",
                "breq 4f",
                "rjmp 1b",
                "4:",
                "clr r1",
            c0 = out(reg) c0,
            c1 = out(reg) c1,
            c2 = out(reg) c2,
            c3 = out(reg) c3,
            c4 = out(reg) c4,
            c5 = out(reg) c5,
            c6 = out(reg) c6,
            c7 = out(reg) c7,
            c8 = out(reg) c8,
            z = out(reg) _,
            n = inout(reg) n => _,
            inout("X") a => _,
            inout("Z") b => _,
            out("r18") _, out("r19") _, out("r20") _, out("r21") _,
            out("r22") _, out("r23") _, out("r24") _, out("r25") _,
            options(readonly, nostack),
        );
    }
    let low = i64::from_le_bytes([c0, c1, c2, c3, c4, c5, c6, c7]);
    // The 72-bit value is c8 * 2^64 + (low as u64); it fits i64 when c8 is
    // the sign extension of low.
    let ext = if low < 0 { 0xFF } else { 0x00 };
    if c8 == ext {
        low
    } else if (c8 as i8) < 0 {
        i64::MIN
    } else {
        i64::MAX
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
    #[inline]
    fn to_q16(self) -> Option<i32> {
        Some(self.0)
    }
    #[inline]
    fn from_q16(bits: i32) -> Self {
        Q16Mac(bits)
    }
}

/// The narrower MAC: `sum x[i] c[i]` of Q15.16 values `x` (i32) and
/// 16-bit coefficients `c` (i16), exact (a 56-bit accumulator; on the AVR
/// 8 hardware `MUL`s per term instead of 16). The caller scales: with `c`
/// in Q`f` format, the sum has `16 + f` fraction bits.
///
/// Measured by the firmware's `fgm-bench` build as the cost a Kalman step
/// with 16-bit gains would have; not yet used by the loop.
///
/// ```
/// use kestrel_avr_rt::mac::dot_q16_i16;
/// // 1.5 * 0.25 + (-2.0) * 0.5 with the coefficients in Q14.
/// let x = [98_304, -131_072]; // 1.5, -2.0 in Q16
/// let c = [4096, 8192];       // 0.25, 0.5 in Q14
/// assert_eq!(dot_q16_i16(&x, &c) as f64 / (1u64 << 30) as f64, -0.625);
/// ```
pub fn dot_q16_i16(x: &[i32], c: &[i16]) -> i64 {
    let n = x.len().min(c.len());
    #[cfg(target_arch = "avr")]
    if (1..=255).contains(&n) {
        // SAFETY: both slices hold at least `n` elements.
        return unsafe { dot_q16_i16_avr(x.as_ptr(), c.as_ptr(), n as u8) };
    }
    let mut acc: i64 = 0;
    for (a, b) in x.iter().zip(c.iter()).take(n) {
        acc += *a as i64 * *b as i64;
    }
    acc
}

/// # Safety
/// `x` and `c` must point to at least `n >= 1` readable elements.
#[cfg(target_arch = "avr")]
#[inline(never)]
unsafe fn dot_q16_i16_avr(x: *const i32, c: *const i16, n: u8) -> i64 {
    let (c0, c1, c2, c3, c4, c5, c6): (u8, u8, u8, u8, u8, u8, u8);
    // SAFETY: reads 4 n and 2 n bytes (the caller's contract); r1 is cleared at the end.
    unsafe {
        core::arch::asm!(
            "clr {c0}",
            "clr {c1}",
            "clr {c2}",
            "clr {c3}",
            "clr {c4}",
            "clr {c5}",
            "clr {c6}",
            "clr {z}",
            "1:",
            "ld r22, X+",
            "ld r23, X+",
            "ld r24, X+",
            "ld r25, X+",
            "ld r18, Z+",
            "ld r19, Z+",
            "mul r22, r18",
            "add {c0}, r0",
            "adc {c1}, r1",
            "adc {c2}, {z}",
            "adc {c3}, {z}",
            "adc {c4}, {z}",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r22, r19",
            "add {c1}, r0",
            "adc {c2}, r1",
            "adc {c3}, {z}",
            "adc {c4}, {z}",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r23, r18",
            "add {c1}, r0",
            "adc {c2}, r1",
            "adc {c3}, {z}",
            "adc {c4}, {z}",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r23, r19",
            "add {c2}, r0",
            "adc {c3}, r1",
            "adc {c4}, {z}",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r24, r18",
            "add {c2}, r0",
            "adc {c3}, r1",
            "adc {c4}, {z}",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r24, r19",
            "add {c3}, r0",
            "adc {c4}, r1",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r25, r18",
            "add {c3}, r0",
            "adc {c4}, r1",
            "adc {c5}, {z}",
            "adc {c6}, {z}",
            "mul r25, r19",
            "add {c4}, r0",
            "adc {c5}, r1",
            "adc {c6}, {z}",
            "sbrs r25, 7",
            "rjmp 2f",
            "sub {c4}, r18",
            "sbc {c5}, r19",
            "sbc {c6}, {z}",
            "sbrc r19, 7",
            "inc {c6}",
            "2:",
            "sbrs r19, 7",
            "rjmp 3f",
            "sub {c2}, r22",
            "sbc {c3}, r23",
            "sbc {c4}, r24",
            "sbc {c5}, r25",
            "sbc {c6}, {z}",
            "3:",
            "dec {n}",
            "breq 4f",
            "rjmp 1b",
            "4:",
            "clr r1",
            c0 = out(reg) c0,
            c1 = out(reg) c1,
            c2 = out(reg) c2,
            c3 = out(reg) c3,
            c4 = out(reg) c4,
            c5 = out(reg) c5,
            c6 = out(reg) c6,
            z = out(reg) _,
            n = inout(reg) n => _,
            inout("X") x => _,
            inout("Z") c => _,
            out("r18") _, out("r19") _,
            out("r22") _, out("r23") _, out("r24") _, out("r25") _,
            options(readonly, nostack),
        );
    }
    // Sign-extend the 56-bit sum.
    i64::from_le_bytes([0, c0, c1, c2, c3, c4, c5, c6]) >> 8
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
        // The narrow MAC against plain 64-bit arithmetic.
        let c: [i16; 5] = core::array::from_fn(|i| (y[i] >> 8) as i16);
        let mut want: i64 = 0;
        for i in 0..5 {
            want += x[i] as i64 * c[i] as i64;
        }
        if dot_q16_i16(&x, &c) != want {
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
