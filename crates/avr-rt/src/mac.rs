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
//! The 16-bit-coefficient kernels of [`crate::kalman16`] and
//! [`crate::fgm16`] are here too: [`dot_q16_i16`], [`row_q16_i16`] (one
//! rounded, saturated row of Q15.16 values and `i16` coefficients) and the
//! routine behind `Row16::apply_all`/`Row16::add_all` that runs every row
//! of a table in one call, all AVR assembly checked at boot against plain
//! 64-bit arithmetic, plus the saturating sums [`add_sat_i32`] and
//! [`sub_sat_i32`].
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
    /// AVR the whole loop is one assembly kernel (`dot_wide_avr`) with a
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

/// The narrower MAC: `sum x[i] c[i]` of Q15.16 values `x` (i32) and
/// 16-bit coefficients `c` (i16), exact (a 56-bit accumulator; on the AVR
/// 8 hardware `MUL`s per term instead of 16). The caller scales: with `c`
/// in Q`f` format, the sum has `16 + f` fraction bits.
///
/// Timed by the firmware's `fgm-bench` build; the loop's kernels use the
/// row routines ([`row_q16_i16`], `Row16::apply_all`), which also round.
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

/// One fixed-point row: `round(sum x[i] c[i] / 2^shift)` of Q15.16 values
/// `x` and 16-bit coefficients `c` (with `shift` fraction bits), ties
/// rounded up, saturated to `i32`; shifts above 48 are taken as 48.
///
/// The sum is exact and rounded once, so this is
/// `round_shift(dot_q16_i16(x, c), shift)` bit for bit. On the AVR the
/// whole row (products, accumulation, rounding shift, saturation) is one
/// assembly routine: each term is 8 hardware
/// multiplies (`MUL`, `MULSU`, `MULS` on the signed bytes, so no sign
/// corrections) into a 48-bit product added to a 56-bit accumulator, about
/// 68 cycles; the shift moves whole bytes first, then single bits.
///
/// ```
/// use kestrel_avr_rt::mac::row_q16_i16;
/// // 1.5 * 0.25 + (-2.0) * 0.5 with the coefficients in Q14: -0.625 in Q16.
/// assert_eq!(row_q16_i16(&[98_304, -131_072], &[4096, 8192], 14), -40_960);
/// ```
#[inline]
pub fn row_q16_i16(x: &[i32], c: &[i16], shift: u8) -> i32 {
    let n = x.len().min(c.len());
    #[cfg(target_arch = "avr")]
    if (1..=255).contains(&n) {
        // SAFETY: both slices hold at least `n` (1..=255) elements.
        return unsafe { row_q16_i16_avr(x.as_ptr(), c.as_ptr(), n as u8, shift.min(48)) };
    }
    let mut acc: i64 = 0;
    for (a, b) in x.iter().zip(c.iter()).take(n) {
        acc += *a as i64 * *b as i64;
    }
    round_shift_i64(acc, shift)
}

/// `round(acc / 2^shift)` (ties up), saturated to `i32`; shifts above 48
/// are taken as 48 (the portable form of the rounding in [`row_q16_i16`]).
#[inline]
fn round_shift_i64(acc: i64, shift: u8) -> i32 {
    let s = shift.min(48);
    let v = if s == 0 {
        acc
    } else {
        // floor(acc / 2^(s-1)), then round the last bit away (no overflow).
        let q = acc >> (s - 1);
        (q >> 1) + (q & 1)
    };
    v.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

/// The AVR routine of [`row_q16_i16`].
///
/// Registers: accumulator `r10`-`r16`, product `r2`-`r7` (pairs for
/// `MOVW`), sign byte `r8`, zero `r9`, count `r17`, `x` bytes `r18`-`r21`,
/// `c` bytes `r22`-`r23` (the signed multiplies need `r16`-`r23`), shift
/// `r24`. Kernels that run several rows use the rows routine instead
/// (one call, one register save for all rows).
///
/// # Safety
/// `x` and `c` must point to at least `n >= 1` readable elements; `shift <= 48`.
#[cfg(target_arch = "avr")]
#[inline(never)]
unsafe fn row_q16_i16_avr(x: *const i32, c: *const i16, n: u8, shift: u8) -> i32 {
    let (b0, b1, b2, b3): (u8, u8, u8, u8);
    // SAFETY: reads 4 n bytes from `x` and 2 n bytes from `c` (the
    // caller's contract); r0/r1 receive the MUL results and r1 (the zero
    // register) is cleared at the end.
    unsafe {
        core::arch::asm!(
            "clr r9",
            "clr r10",
            "clr r11",
            "clr r12",
            "clr r13",
            "clr r14",
            "clr r15",
            "clr r16",
            // ---- one term: t = x * c (48-bit signed) in r2..r7
            "1:",
            "ld r18, X+",
            "ld r19, X+",
            "ld r20, X+",
            "ld r21, X+",
            "ld r22, Z+",
            "ld r23, Z+",
            "mul r18, r22",  // x0 c0 at byte 0 (unsigned)
            "movw r2, r0",
            "mul r20, r22",  // x2 c0 at byte 2 (unsigned)
            "movw r4, r0",
            "muls r21, r23", // x3 c1 at byte 4 (signed, the top)
            "movw r6, r0",
            "mul r19, r22",  // x1 c0 at byte 1 (unsigned)
            "add r3, r0",
            "adc r4, r1",
            "adc r5, r9",
            "adc r6, r9",
            "adc r7, r9",
            "mulsu r23, r18", // c1 x0 at byte 1 (signed; C = its sign)
            "sbc r8, r8",
            "add r3, r0",
            "adc r4, r1",
            "adc r5, r8",
            "adc r6, r8",
            "adc r7, r8",
            "mulsu r23, r19", // c1 x1 at byte 2
            "sbc r8, r8",
            "add r4, r0",
            "adc r5, r1",
            "adc r6, r8",
            "adc r7, r8",
            "mulsu r23, r20", // c1 x2 at byte 3
            "sbc r8, r8",
            "add r5, r0",
            "adc r6, r1",
            "adc r7, r8",
            "mulsu r21, r22", // x3 c0 at byte 3
            "sbc r8, r8",
            "add r5, r0",
            "adc r6, r1",
            "adc r7, r8",
            // ---- acc += t (sign-extended)
            "mov r8, r7",
            "lsl r8",
            "sbc r8, r8",
            "add r10, r2",
            "adc r11, r3",
            "adc r12, r4",
            "adc r13, r5",
            "adc r14, r6",
            "adc r15, r7",
            "adc r16, r8",
            "dec r17",
            "breq 2f",
            "rjmp 1b",
            // ---- round(acc / 2^shift): shift by shift - 1, then halve rounding up
            "2:",
            "tst r24",
            "breq 9f",
            "dec r24",
            "3:",
            "cpi r24, 8",
            "brlo 4f",
            "mov r10, r11",
            "mov r11, r12",
            "mov r12, r13",
            "mov r13, r14",
            "mov r14, r15",
            "mov r15, r16",
            "lsl r16",
            "sbc r16, r16",
            "subi r24, 8",
            "rjmp 3b",
            "4:",
            "tst r24",
            "breq 6f",
            "5:",
            "asr r16",
            "ror r15",
            "ror r14",
            "ror r13",
            "ror r12",
            "ror r11",
            "ror r10",
            "dec r24",
            "brne 5b",
            "6:",
            "asr r16",
            "ror r15",
            "ror r14",
            "ror r13",
            "ror r12",
            "ror r11",
            "ror r10",
            "adc r10, r9",
            "adc r11, r9",
            "adc r12, r9",
            "adc r13, r9",
            "adc r14, r9",
            "adc r15, r9",
            "adc r16, r9",
            // ---- saturate to i32: bytes 4..6 must extend byte 3's sign
            "9:",
            "mov r8, r13",
            "lsl r8",
            "sbc r8, r8",
            "cp r14, r8",
            "cpc r15, r8",
            "cpc r16, r8",
            "breq 7f",
            "mov r10, r16",
            "lsl r10",
            "sbc r10, r10",
            "com r10",
            "mov r11, r10",
            "mov r12, r10",
            "mov r13, r10",
            "ldi r24, 0x80",
            "eor r13, r24",
            "7:",
            "clr r1",
            out("r2") _, out("r3") _, out("r4") _, out("r5") _,
            out("r6") _, out("r7") _, out("r8") _, out("r9") _,
            out("r10") b0, out("r11") b1, out("r12") b2, out("r13") b3,
            out("r14") _, out("r15") _, out("r16") _,
            inout("r17") n => _,
            out("r18") _, out("r19") _, out("r20") _, out("r21") _,
            out("r22") _, out("r23") _,
            inout("r24") shift => _,
            inout("X") x => _,
            inout("Z") c => _,
            options(readonly, nostack),
        );
    }
    i32::from_le_bytes([b0, b1, b2, b3])
}

/// The body of [`rows_q16_i16_avr`]; the optional instructions run after
/// the rounding, before the saturation (the accumulate step).
#[cfg(target_arch = "avr")]
macro_rules! rows_asm {
    ($n:expr, $rows:expr, $count:expr, $v:expr, $out:expr; $($acc:literal),*) => {
        core::arch::asm!(
            "push r28",
            "push r29",
            "push r20",
            "movw r28, r18",
            "clr r9",
            // ---- row set-up: start (clamped to N), X = v + 4 start, Z += 2 start
            "20:",
            "ldd r17, Z+{st}",
            "cpi r17, {n}",
            "brlo 21f",
            "ldi r17, {n}",
            "21:",
            "movw r26, r24",
            "mov r18, r17",
            "lsl r18",
            "add r30, r18",
            "adc r31, r9",
            "lsl r18",
            "add r26, r18",
            "adc r27, r9",
            "ldi r18, {n}",
            "sub r18, r17",
            "mov r17, r18",
            "clr r10",
            "clr r11",
            "movw r12, r10",
            "movw r14, r10",
            "clr r16",
            "tst r17",
            "brne 22f",
            "rjmp 23f",
            // ---- one term: x (r18..r21) times c (r22, r23)
            "22:",
            "ld r18, X+",
            "ld r19, X+",
            "ld r20, X+",
            "ld r21, X+",
            "ld r22, Z+",
            "ld r23, Z+",
            // x fits 24 bits (byte 3 extends byte 2's sign: r21 xor sign
            // is zero): the short term, otherwise the full one
            "sbrc r20, 7",
            "com r21",
            "cpse r21, r9",
            "rjmp 36f",
            // short term: t = x * c (40-bit signed, six products) in
            // r2, r3, r6, r4, r5 (bytes 0..4), acc += t
            "mul r18, r22",
            "movw r2, r0",
            "muls r20, r23",
            "movw r4, r0",
            "mulsu r20, r22",
            "sbc r8, r8",
            "mov r6, r0",
            "add r4, r1",
            "adc r5, r8",
            "mul r19, r22",
            "add r3, r0",
            "adc r6, r1",
            "adc r4, r9",
            "adc r5, r9",
            "mulsu r23, r18",
            "sbc r8, r8",
            "add r3, r0",
            "adc r6, r1",
            "adc r4, r8",
            "adc r5, r8",
            "mulsu r23, r19",
            "sbc r8, r8",
            "add r6, r0",
            "adc r4, r1",
            "adc r5, r8",
            "mov r8, r5",
            "lsl r8",
            "sbc r8, r8",
            "add r10, r2",
            "adc r11, r3",
            "adc r12, r6",
            "adc r13, r4",
            "adc r14, r5",
            "adc r15, r8",
            "adc r16, r8",
            "dec r17",
            "brne 22b",
            "rjmp 23f",
            // full term: restore byte 3, t = x * c (48-bit signed) in
            // r2..r7, acc += t
            "36:",
            "sbrc r20, 7",
            "com r21",
            "mul r18, r22",
            "movw r2, r0",
            "mul r20, r22",
            "movw r4, r0",
            "muls r21, r23",
            "movw r6, r0",
            "mul r19, r22",
            "add r3, r0",
            "adc r4, r1",
            "adc r5, r9",
            "adc r6, r9",
            "adc r7, r9",
            "mulsu r23, r18",
            "sbc r8, r8",
            "add r3, r0",
            "adc r4, r1",
            "adc r5, r8",
            "adc r6, r8",
            "adc r7, r8",
            "mulsu r23, r19",
            "sbc r8, r8",
            "add r4, r0",
            "adc r5, r1",
            "adc r6, r8",
            "adc r7, r8",
            "mulsu r23, r20",
            "sbc r8, r8",
            "add r5, r0",
            "adc r6, r1",
            "adc r7, r8",
            "mulsu r21, r22",
            "sbc r8, r8",
            "add r5, r0",
            "adc r6, r1",
            "adc r7, r8",
            "add r10, r2",
            "adc r11, r3",
            "adc r12, r4",
            "adc r13, r5",
            "adc r14, r6",
            "adc r15, r7",
            "adc r16, r9",
            "sbrc r7, 7", // t < 0: its sign extension 0xFF into the top byte
            "dec r16",
            "dec r17",
            "breq 23f",
            "rjmp 22b",
            // ---- Z is at the shift byte: read it, skip start (next row)
            "23:",
            "ld r17, Z+",
            "adiw r30, 1",
            "cpi r17, 49",
            "brlo 34f",
            "ldi r17, 48",
            "34:",
            "tst r17",
            "brne 24f",
            "rjmp 29f",
            "24:",
            "dec r17",
            // whole bytes: two at a time, then one
            "25:",
            "cpi r17, 16",
            "brlo 35f",
            "movw r10, r12",
            "movw r12, r14",
            "mov r14, r16",
            "lsl r16",
            "sbc r16, r16",
            "mov r15, r16",
            "subi r17, 16",
            "rjmp 25b",
            "35:",
            "cpi r17, 8",
            "brlo 26f",
            "mov r10, r11",
            "mov r11, r12",
            "mov r12, r13",
            "mov r13, r14",
            "mov r14, r15",
            "mov r15, r16",
            "lsl r16",
            "sbc r16, r16",
            "subi r17, 8",
            // 4 to 7 bits (b) and the rounding bit: round(V / 2^(b+1)) =
            // floor((V 2^(7-b) + 2^7) / 2^8): left by 7 - b bits (no
            // overflow: after a byte move the top byte is the sign, without
            // one |V| < 2^52), then one byte right, adding the dropped
            // byte's top bit
            "26:",
            "cpi r17, 4",
            "brlo 28f",
            "subi r17, 7",
            "breq 38f",
            "37:",
            "lsl r10",
            "rol r11",
            "rol r12",
            "rol r13",
            "rol r14",
            "rol r15",
            "rol r16",
            "inc r17",
            "brne 37b",
            "38:",
            "lsl r10",
            "adc r11, r9",
            "adc r12, r9",
            "adc r13, r9",
            "adc r14, r9",
            "adc r15, r9",
            "adc r16, r9",
            "mov r10, r11",
            "mov r11, r12",
            "mov r12, r13",
            "mov r13, r14",
            "mov r14, r15",
            "mov r15, r16",
            "lsl r16",
            "sbc r16, r16",
            "rjmp 29f",
            // 0 to 3 bits right
            "28:",
            "tst r17",
            "breq 30f",
            "31:",
            "asr r16",
            "ror r15",
            "ror r14",
            "ror r13",
            "ror r12",
            "ror r11",
            "ror r10",
            "dec r17",
            "brne 31b",
            // the last bit: halve, rounding up
            "30:",
            "asr r16",
            "ror r15",
            "ror r14",
            "ror r13",
            "ror r12",
            "ror r11",
            "ror r10",
            "adc r10, r9",
            "adc r11, r9",
            "adc r12, r9",
            "adc r13, r9",
            "adc r14, r9",
            "adc r15, r9",
            "adc r16, r9",
            // ---- saturate to i32 (bytes 4..6 must extend byte 3's sign), store
            "29:",
            $($acc,)*
            "mov r8, r13",
            "lsl r8",
            "sbc r8, r8",
            "cp r14, r8",
            "cpc r15, r8",
            "cpc r16, r8",
            "breq 32f",
            "mov r10, r16",
            "lsl r10",
            "sbc r10, r10",
            "com r10",
            "mov r11, r10",
            "mov r12, r10",
            "mov r13, r10",
            "ldi r18, 0x80",
            "eor r13, r18",
            "32:",
            "st Y+, r10",
            "st Y+, r11",
            "st Y+, r12",
            "st Y+, r13",
            "pop r20",
            "dec r20",
            "breq 33f",
            "push r20",
            "rjmp 20b",
            "33:",
            "pop r29",
            "pop r28",
            "clr r1",
            n = const $n,
            st = const 2 * $n + 1,
            out("r2") _, out("r3") _, out("r4") _, out("r5") _,
            out("r6") _, out("r7") _, out("r8") _, out("r9") _,
            out("r10") _, out("r11") _, out("r12") _, out("r13") _,
            out("r14") _, out("r15") _, out("r16") _, out("r17") _,
            inout("r18") ($out as usize) as u8 => _,
            inout("r19") (($out as usize) >> 8) as u8 => _,
            inout("r20") $count => _,
            out("r21") _, out("r22") _, out("r23") _,
            in("r24") ($v as usize) as u8,
            in("r25") (($v as usize) >> 8) as u8,
            out("X") _,
            inout("Z") $rows => _,
        )
    };
}

/// Several fixed-point rows over one vector: `out[i] = round(sum_{j >=
/// start_i} c_i[j] v[j] / 2^shift_i)` (each as [`row_q16_i16`]), or with
/// `ACC` `out[i] = sat(out[i] + round(...))` (the rounded row added to the
/// value in `out` before the one saturation), for rows
/// stored as `#[repr(C)]` records `{ c: [i16; N], shift: u8, start: u8 }`
/// (`crate::kalman16::Row16`), a start above `N` taken as `N`, a shift
/// above 48 as 48.
///
/// On the AVR one assembly routine runs all rows (one call, one register
/// save; per row only the pointer set-up, the rounding and four stores
/// beyond the multiply-adds). A term whose value fits 24 bits (the top
/// byte only extends the sign) takes six hardware multiplies into a 40-bit
/// product (60 cycles), any other eight into a 48-bit one (76 cycles);
/// both add exactly into the same 56-bit accumulator.
///
/// # Safety
/// `rows` must point to `count >= 1` such records, `v` to `N` readable
/// values, `out` to `count` writable values; `1 <= N <= 31`.
#[cfg(target_arch = "avr")]
#[inline(never)]
pub(crate) unsafe fn rows_q16_i16_avr<const N: usize, const ACC: bool>(
    rows: *const u8,
    count: u8,
    v: *const i32,
    out: *mut i32,
) {
    // SAFETY: reads `count` records and `N` values, reads (with `ACC`) and
    // writes `count` values (the caller's contract); Y is saved and
    // restored around its use as the output pointer; r0/r1 receive the MUL
    // results and r1 (the zero register) is cleared at the end.
    unsafe {
        if ACC {
            rows_asm!(N, rows, count, v, out;
                // acc += out[i] (sign-extended), r18..r21 are free here
                "ldd r18, Y+0",
                "ldd r19, Y+1",
                "ldd r20, Y+2",
                "ldd r21, Y+3",
                "mov r8, r21",
                "lsl r8",
                "sbc r8, r8",
                "add r10, r18",
                "adc r11, r19",
                "adc r12, r20",
                "adc r13, r21",
                "adc r14, r8",
                "adc r15, r8",
                "adc r16, r8");
        } else {
            rows_asm!(N, rows, count, v, out;);
        }
    }
}

/// `a + b` saturated to `i32` (`i32::saturating_add`); on the AVR four
/// register additions and one overflow test instead of LLVM's generic
/// sequence (about 45 cycles).
#[inline(always)]
pub fn add_sat_i32(a: i32, b: i32) -> i32 {
    #[cfg(target_arch = "avr")]
    {
        let [mut a0, mut a1, mut a2, mut a3] = a.to_le_bytes();
        let [b0, b1, b2, b3] = b.to_le_bytes();
        // SAFETY: register-only arithmetic.
        unsafe {
            core::arch::asm!(
                "add {a0}, {b0}",
                "adc {a1}, {b1}",
                "adc {a2}, {b2}",
                "adc {a3}, {b3}",
                "brvc 1f",
                // Overflow: both operands had b's sign; saturate towards it.
                "mov {a0}, {b3}",
                "lsl {a0}",
                "sbc {a0}, {a0}",
                "com {a0}",
                "mov {a1}, {a0}",
                "mov {a2}, {a0}",
                "mov {a3}, {a0}",
                "subi {a3}, 0x80",
                "1:",
                a0 = inout(reg) a0,
                a1 = inout(reg) a1,
                a2 = inout(reg) a2,
                a3 = inout(reg_upper) a3,
                b0 = in(reg) b0,
                b1 = in(reg) b1,
                b2 = in(reg) b2,
                b3 = in(reg) b3,
                options(pure, nomem, nostack),
            );
        }
        i32::from_le_bytes([a0, a1, a2, a3])
    }
    #[cfg(not(target_arch = "avr"))]
    {
        a.saturating_add(b)
    }
}

/// `a - b` saturated to `i32` (`i32::saturating_sub`), as [`add_sat_i32`].
#[inline(always)]
pub fn sub_sat_i32(a: i32, b: i32) -> i32 {
    #[cfg(target_arch = "avr")]
    {
        let [mut a0, mut a1, mut a2, mut a3] = a.to_le_bytes();
        let [b0, b1, b2, b3] = b.to_le_bytes();
        // SAFETY: register-only arithmetic.
        unsafe {
            core::arch::asm!(
                "sub {a0}, {b0}",
                "sbc {a1}, {b1}",
                "sbc {a2}, {b2}",
                "sbc {a3}, {b3}",
                "brvc 1f",
                // Overflow: a had the sign opposite to b's; saturate towards it.
                "mov {a0}, {b3}",
                "lsl {a0}",
                "sbc {a0}, {a0}",
                "mov {a1}, {a0}",
                "mov {a2}, {a0}",
                "mov {a3}, {a0}",
                "subi {a3}, 0x80",
                "1:",
                a0 = inout(reg) a0,
                a1 = inout(reg) a1,
                a2 = inout(reg) a2,
                a3 = inout(reg_upper) a3,
                b0 = in(reg) b0,
                b1 = in(reg) b1,
                b2 = in(reg) b2,
                b3 = in(reg) b3,
                options(pure, nomem, nostack),
            );
        }
        i32::from_le_bytes([a0, a1, a2, a3])
    }
    #[cfg(not(target_arch = "avr"))]
    {
        a.saturating_sub(b)
    }
}

/// Compares [`Q16Mac`] with [`Q16`] on `n` pseudo-random products and
/// 5-element dot products, [`dot_q16_i16`] with 64-bit arithmetic, and
/// (every fourth round) [`row_q16_i16`] and the rows routine of
/// `Row16::apply_all` with 64-bit arithmetic (a linear congruential
/// sequence from `seed`, mixing small, full-range and 24-bit boundary
/// values, every shift, saturation); returns the number of mismatches.
/// The firmware runs it at boot, so the AVR assembly is checked on target.
pub fn self_test(seed: u32, n: u16) -> u16 {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        // Mix full-range values, values of a few units and values at the
        // 24-bit boundary of the rows routine's short term (2^23 - 2 to
        // 2^23 + 1 and their negatives).
        if s & 0x100 != 0 {
            s as i32
        } else if s & 0x200 != 0 {
            (s as i32) >> 12
        } else {
            (((s as i32) >> 31) ^ 0x7F_FFFF) + ((s >> 12) & 3) as i32 - 1
        }
    };
    let mut bad = 0u16;
    for k in 0..n {
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
        // The f32 conversion routine of the f32 loop (`to_q16_all`) against
        // `to_q16` value by value: random bits (any exponent, NaN and
        // infinities), and exponents 100 to 150 (the rounding, shifting
        // and saturating cases).
        let f: [f32; 4] = core::array::from_fn(|i| {
            let b = next() as u32;
            let e = 100 + (next() as u32 >> 8) % 51;
            f32::from_bits(if i == 3 && k % 2 == 0 {
                b
            } else {
                (b & 0x807F_FFFF) | (e << 23)
            })
        });
        let mut fast = [0i32; 4];
        let all = <f32 as crate::output::RtScalar>::to_q16_all(&f, &mut fast);
        let each: Option<[i32; 4]> = (|| {
            let mut o = [0i32; 4];
            for (o, x) in o.iter_mut().zip(&f) {
                *o = crate::output::RtScalar::to_q16(*x)?;
            }
            Some(o)
        })();
        if all.is_some() != each.is_some() || each.is_some_and(|e| e != fast) {
            bad += 1;
        }
        // The saturating additions against core's.
        let (p, q) = (next(), next());
        if add_sat_i32(p, q) != p.saturating_add(q) || sub_sat_i32(p, q) != p.saturating_sub(q) {
            bad += 1;
        }
        // The row kernels against 64-bit arithmetic, every fourth round
        // (the reference's 64-bit shifts are slow on the AVR, and the
        // firmware's boot report must come within two periods).
        if k % 4 != 0 {
            continue;
        }
        // One row (full-range values, every shift, saturation).
        let xf: [i32; 5] = core::array::from_fn(|_| next());
        let cf: [i16; 5] = core::array::from_fn(|_| (next() >> 4) as i16);
        let shift = (next() as u32 % 50) as u8;
        let len = 1 + (next() as u32 % 5) as usize;
        let sum: i64 = xf
            .iter()
            .zip(cf.iter())
            .take(len)
            .map(|(a, b)| *a as i64 * *b as i64)
            .sum();
        if row_q16_i16(&xf[..len], &cf[..len], shift) != round_shift_i64(sum, shift) {
            bad += 1;
        }
        // The rows routine (three rows with their own starts and shifts,
        // starts beyond the row and shifts beyond 48 included).
        let rows: [crate::kalman16::Row16<5>; 3] = core::array::from_fn(|_| {
            crate::kalman16::Row16::new(
                core::array::from_fn(|_| (next() >> 4) as i16),
                (next() as u32 % 52) as u8,
                (next() as u32 % 7) as u8,
            )
        });
        let got = crate::kalman16::Row16::apply_all(&rows, &xf);
        let mut acc: [i32; 3] = core::array::from_fn(|_| next());
        let base = acc;
        crate::kalman16::Row16::add_all(&rows, &xf, &mut acc);
        for (((r, g), a), b) in rows.iter().zip(got.iter()).zip(acc.iter()).zip(base.iter()) {
            let sum: i64 = xf
                .iter()
                .zip(r.c.iter())
                .skip(r.start as usize)
                .map(|(a, b)| *a as i64 * *b as i64)
                .sum();
            if *g != round_shift_i64(sum, r.shift) {
                bad += 1;
            }
            // add_all: one saturation of base + rounded row (the rounded
            // row fits i64: |sum| < 2^50).
            let s = r.shift.min(48);
            let rounded = if s == 0 {
                sum
            } else {
                let q = sum >> (s - 1);
                (q >> 1) + (q & 1)
            };
            let want = (*b as i64 + rounded).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            if *a != want {
                bad += 1;
            }
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

    /// The rounded, saturated row in 128-bit arithmetic (independent of
    /// the kernel's shift-then-halve rounding).
    fn row_reference(x: &[i32], c: &[i16], shift: u8) -> i32 {
        let s = shift.min(48) as u32;
        let sum: i128 = x.iter().zip(c).map(|(a, b)| *a as i128 * *b as i128).sum();
        let half = if s == 0 { 0 } else { 1i128 << (s - 1) };
        let q = (sum + half).div_euclid(1i128 << s);
        q.clamp(i32::MIN as i128, i32::MAX as i128) as i32
    }

    #[test]
    fn row_corners() {
        let big = [i32::MAX, i32::MIN, i32::MAX, i32::MIN];
        let c = [i16::MIN, i16::MIN, i16::MAX, i16::MAX];
        for shift in 0..=60u8 {
            for n in 0..=4 {
                assert_eq!(
                    row_q16_i16(&big[..n], &c[..n], shift),
                    row_reference(&big[..n], &c[..n], shift),
                    "n {n} shift {shift}"
                );
            }
        }
        // Ties round up (towards +inf), as Q16.
        assert_eq!(row_q16_i16(&[3], &[1], 1), 2);
        assert_eq!(row_q16_i16(&[-3], &[1], 1), -1);
        assert_eq!(row_q16_i16(&[], &[], 3), 0);
    }

    #[test]
    fn saturating_sums_at_the_limits() {
        let v = [i32::MIN, i32::MIN + 1, -1, 0, 1, i32::MAX - 1, i32::MAX];
        for &a in &v {
            for &b in &v {
                assert_eq!(add_sat_i32(a, b), a.saturating_add(b), "{a} + {b}");
                assert_eq!(sub_sat_i32(a, b), a.saturating_sub(b), "{a} - {b}");
            }
        }
    }

    proptest! {
        #[test]
        fn row_is_the_rounded_saturated_sum(
            v in proptest::collection::vec((any::<i32>(), any::<i16>()), 0..12),
            shift in 0u8..=60,
        ) {
            let x: Vec<i32> = v.iter().map(|p| p.0).collect();
            let c: Vec<i16> = v.iter().map(|p| p.1).collect();
            prop_assert_eq!(row_q16_i16(&x, &c, shift), row_reference(&x, &c, shift));
        }

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
