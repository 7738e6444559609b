//! Assembly text shared by the AVR routines (`explicit/tree16/walk_avr.rs`, the
//! `f32` conversions of `output.rs`): one text per operation, made unique
//! in each routine by a label prefix and tag.

/// `r16:r19 = round(r16:r19 / 2^(n + 1))` (arithmetic, half up) for the
/// counter register `n` (clobbered; r2 is zero): a byte move per 8 bits of
/// the shift, then one 4-cycle pass per bit, the last bit's carry added
/// back. The local labels are `{p}{l}byte`, `{p}{l}bits`, `{p}{l}bit` and
/// `{p}{l}last`.
#[rustfmt::skip]
macro_rules! round_shift {
    ($p:literal, $n:literal, $l:literal) => {
        concat!(
            "dec ", $n, "\n",
            $p, $l, "byte:\n",
            "cpi ", $n, ", 8\n",
            "brlo ", $p, $l, "bits\n",
            "mov r16, r17\n",
            "mov r17, r18\n",
            "mov r18, r19\n",
            "lsl r19\n",
            "sbc r19, r19\n",
            "subi ", $n, ", 8\n",
            "rjmp ", $p, $l, "byte\n",
            $p, $l, "bits:\n",
            "tst ", $n, "\n",
            "breq ", $p, $l, "last\n",
            $p, $l, "bit:\n",
            "asr r19\n",
            "ror r18\n",
            "ror r17\n",
            "ror r16\n",
            "dec ", $n, "\n",
            "brne ", $p, $l, "bit\n",
            $p, $l, "last:\n",
            "asr r19\n",
            "ror r18\n",
            "ror r17\n",
            "ror r16\n",
            "adc r16, r2\n",
            "adc r17, r2\n",
            "adc r18, r2\n",
            "adc r19, r2",
        )
    };
}

/// [`crate::output::RtScalar::to_q16`] for `f32`: the bits in r16:r19 to
/// Q15.16 in r16:r19. `e` (the exponent, in r21) and the sign mask (in
/// register `s`): `e = 255` (not finite): `rjmp nonfinite`; `e >= 142`
/// (`|v| >= 2^15`): saturated; `e < 110` (`|v| < 2^-17`, subnormals, zero):
/// 0; `e < 134`: the mantissa with its implicit bit rounded half up by
/// `134 - e` bits ([`round_shift`] with counter register `n`, r16-r31);
/// otherwise shifted left by `e - 134`; then the sign. Ends at the label
/// `{p}{l}done` (falls through). Clobbers r21 and `n`; r2 is zero.
#[rustfmt::skip]
macro_rules! f32_to_q16 {
    ($p:literal, $l:literal, $s:literal, $n:literal, $nonfinite:literal) => {
        concat!(
            "mov r21, r18\n",
            "lsl r21\n",                // C = e's low bit
            "mov r21, r19\n",
            "rol r21\n",                // r21 = e, C = the sign
            "sbc ", $s, ", ", $s, "\n",
            "cpi r21, 0xFF\n",
            "brne ", $p, $l, "fin\n",
            "rjmp ", $nonfinite, "\n",
            $p, $l, "fin:\n",
            "cpi r21, 142\n",           // |v| >= 2^15: saturated
            "brlo ", $p, $l, "ns\n",
            "ldi r16, 0xFF\n",          // i32::MAX
            "ldi r17, 0xFF\n",
            "ldi r18, 0xFF\n",
            "ldi r19, 0x7F\n",
            "tst ", $s, "\n",
            "brne ", $p, $l, "smin\n",
            "rjmp ", $p, $l, "done\n",
            $p, $l, "smin:\n",
            "ldi r16, 0\n",             // i32::MIN
            "ldi r17, 0\n",
            "ldi r18, 0\n",
            "ldi r19, 0x80\n",
            "rjmp ", $p, $l, "done\n",
            $p, $l, "ns:\n",
            "cpi r21, 110\n",           // |v| < 2^-17 (and subnormals, zero): 0
            "brsh ", $p, $l, "nz\n",
            "clr r16\n",
            "clr r17\n",
            "clr r18\n",
            "clr r19\n",
            "rjmp ", $p, $l, "done\n",
            $p, $l, "nz:\n",
            "ori r18, 0x80\n",          // m
            "clr r19\n",
            "cpi r21, 134\n",
            "brsh ", $p, $l, "shl\n",
            "ldi ", $n, ", 134\n",      // round(m / 2^(134 - e)), 1..=24 bits
            "sub ", $n, ", r21\n",
            round_shift!($p, $n, $l), "\n",
            "rjmp ", $p, $l, "sign\n",
            $p, $l, "shl:\n",           // m 2^(e - 134), 0..=7 bits
            "subi r21, 134\n",
            "breq ", $p, $l, "sign\n",
            $p, $l, "shll:\n",
            "lsl r16\n",
            "rol r17\n",
            "rol r18\n",
            "rol r19\n",
            "dec r21\n",
            "brne ", $p, $l, "shll\n",
            $p, $l, "sign:\n",
            "tst ", $s, "\n",
            "breq ", $p, $l, "done\n",
            "com r19\n",                // -v
            "com r18\n",
            "com r17\n",
            "neg r16\n",
            "sbci r17, 0xFF\n",
            "sbci r18, 0xFF\n",
            "sbci r19, 0xFF\n",
            $p, $l, "done:",
        )
    };
}
