//! [`dot_q16_i16`]: the exact sum of Q15.16 values times 16-bit
//! coefficients (8 hardware multiplies per term on the AVR).

/// The narrower MAC: `sum x[i] c[i]` of Q15.16 values `x` (i32) and
/// 16-bit coefficients `c` (i16), exact (a 56-bit accumulator; on the AVR
/// 8 hardware `MUL`s per term instead of 16). The caller scales: with `c`
/// in Q`f` format, the sum has `16 + f` fraction bits.
///
/// Timed by the firmware's `fgm-bench` build; the loop's kernels use the
/// row routines ([`row_q16_i16`](super::row::row_q16_i16), `Row16::apply_all`), which also round.
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
