//! The exact sum of products behind [`Q16Mac`]'s `Scalar::dot`: on the
//! AVR one assembly kernel with a 72-bit accumulator, plain Rust elsewhere.

use super::mul_wide::mul_wide;
use super::q16mac::Q16Mac;

/// The exact sum of products, saturated to i64.
#[cfg(not(target_arch = "avr"))]
#[inline(always)]
pub(super) fn dot_wide(a: &[Q16Mac], b: &[Q16Mac]) -> i64 {
    let mut acc: i64 = 0;
    for (x, y) in a.iter().zip(b.iter()) {
        acc = acc.saturating_add(mul_wide(x.0, y.0));
    }
    acc
}

#[cfg(target_arch = "avr")]
#[inline(always)]
pub(super) fn dot_wide(a: &[Q16Mac], b: &[Q16Mac]) -> i64 {
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
