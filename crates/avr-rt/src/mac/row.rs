//! [`row_q16_i16`]: one rounded, saturated row of Q15.16 values and 16-bit
//! coefficients (one assembly routine on the AVR).

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
pub(super) fn round_shift_i64(acc: i64, shift: u8) -> i32 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
    }
}
