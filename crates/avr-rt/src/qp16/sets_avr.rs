//! The per-set kernel's pass glue on the AVR ([`super::sets`]): the
//! members' residuals, the multipliers with the wrong-sign test, and the
//! primal point with the most-violated scan, each one assembly loop over
//! the variables' records (`sets::Var`: `unc` at 0, `lo` 4, `hi` 8, `w`
//! 12, `star` 16, `pos` 20, `code` 21, `nu` 22; [`VAR_SIZE`] bytes,
//! checked in `sets`). Each computes what the portable loop in `sets` computes, bit
//! for bit (`i32` saturating differences and negation, signed
//! comparisons).

/// The size of one variable's record.
pub(super) const VAR_SIZE: u8 = 26;

/// The members' residuals `unc - (upper ? hi : lo)` (saturated) into `r`
/// in increasing variable order; returns the members' bit mask and count.
///
/// # Safety
/// `var` must point to `n` (1..=8) readable records, `r` to as many
/// writable `i32` as there are members.
#[inline(never)]
pub(super) unsafe fn members_avr(var: *const u8, n: u8, r: *mut i32) -> (u8, u8) {
    let (mask, q): (u8, u8);
    // SAFETY: reads the n records, writes one i32 per member (the
    // caller's contract); register-only otherwise.
    unsafe {
        core::arch::asm!(
            "clr {mask}",
            "clr {q}",
            "ldi {bit}, 1",
            "1:",
            "ldd {t}, Z+20",
            "tst {t}",
            "breq 4f",
            "or {mask}, {bit}",
            "inc {q}",
            "ldd {t}, Z+21",
            "ld {a0}, Z",
            "ldd {a1}, Z+1",
            "ldd {a2}, Z+2",
            "ldd {a3}, Z+3",
            "sbrc {t}, 0",
            "rjmp 2f",
            "ldd {b0}, Z+4",
            "ldd {b1}, Z+5",
            "ldd {b2}, Z+6",
            "ldd {b3}, Z+7",
            "rjmp 3f",
            "2:",
            "ldd {b0}, Z+8",
            "ldd {b1}, Z+9",
            "ldd {b2}, Z+10",
            "ldd {b3}, Z+11",
            "3:",
            "sub {a0}, {b0}",
            "sbc {a1}, {b1}",
            "sbc {a2}, {b2}",
            "sbc {a3}, {b3}",
            "brvc 5f",
            // Overflow: the wrapped sign is the opposite of the true one.
            "lsl {a3}",
            "sbc {a0}, {a0}",
            "mov {a1}, {a0}",
            "mov {a2}, {a0}",
            "mov {a3}, {a0}",
            "subi {a3}, 0x80",
            "5:",
            "st X+, {a0}",
            "st X+, {a1}",
            "st X+, {a2}",
            "st X+, {a3}",
            "4:",
            "adiw r30, {size}",
            "lsl {bit}",
            "dec {n}",
            "brne 1b",
            mask = out(reg) mask,
            q = out(reg) q,
            bit = out(reg_upper) _,
            t = out(reg) _,
            a0 = out(reg) _,
            a1 = out(reg) _,
            a2 = out(reg) _,
            a3 = out(reg_upper) _,
            b0 = out(reg) _,
            b1 = out(reg) _,
            b2 = out(reg) _,
            b3 = out(reg) _,
            n = inout(reg) n => _,
            size = const VAR_SIZE,
            inout("Z") var => _,
            inout("X") r => _,
            options(nostack),
        );
    }
    (mask, q)
}

/// Each member's multiplier (`out` in increasing variable order) into its
/// record's `star`; returns the bit mask (by variable) of the members with
/// `code < 2` whose multiplier, negated (saturated) for a lower bound, is
/// below `limit`.
///
/// # Safety
/// `var` must point to `n` (1..=8) writable records, `out` to as many
/// readable `i32` as there are members.
#[inline(never)]
pub(super) unsafe fn stars_avr(var: *mut u8, n: u8, out: *const i32, limit: i32) -> u8 {
    let cand: u8;
    let [l0, l1, l2, l3] = limit.to_le_bytes();
    // SAFETY: reads and writes the n records, reads one i32 per member
    // (the caller's contract); register-only otherwise.
    unsafe {
        core::arch::asm!(
            "clr {cand}",
            "ldi {bit}, 1",
            "1:",
            "ldd {t}, Z+20",
            "tst {t}",
            "breq 4f",
            "ld {a0}, X+",
            "ld {a1}, X+",
            "ld {a2}, X+",
            "ld {a3}, X+",
            "std Z+16, {a0}",
            "std Z+17, {a1}",
            "std Z+18, {a2}",
            "std Z+19, {a3}",
            "ldd {t}, Z+21",
            "cpi {t}, 2",
            "brsh 4f",
            "sbrc {t}, 0",
            "rjmp 3f",
            // A lower bound: the saturated negation (com, then add 1).
            "com {a0}",
            "com {a1}",
            "com {a2}",
            "com {a3}",
            "subi {a0}, 0xFF",
            "sbci {a1}, 0xFF",
            "sbci {a2}, 0xFF",
            "sbci {a3}, 0xFF",
            "brvc 3f",
            "ldi {a0}, 0xFF",
            "ldi {a1}, 0xFF",
            "ldi {a2}, 0xFF",
            "ldi {a3}, 0x7F",
            "3:",
            "cp {a0}, {l0}",
            "cpc {a1}, {l1}",
            "cpc {a2}, {l2}",
            "cpc {a3}, {l3}",
            "brge 4f",
            "or {cand}, {bit}",
            "4:",
            "adiw r30, {size}",
            "lsl {bit}",
            "dec {n}",
            "brne 1b",
            cand = out(reg) cand,
            bit = out(reg_upper) _,
            t = out(reg_upper) _,
            a0 = out(reg_upper) _,
            a1 = out(reg_upper) _,
            a2 = out(reg_upper) _,
            a3 = out(reg_upper) _,
            l0 = in(reg) l0,
            l1 = in(reg) l1,
            l2 = in(reg) l2,
            l3 = in(reg) l3,
            n = inout(reg) n => _,
            size = const VAR_SIZE,
            inout("Z") var => _,
            inout("X") out => _,
            options(nostack),
        );
    }
    cand
}

/// The point and the most violated bound for `tol >= 0`: a member's
/// `nu` becomes its `star` and its `w` its bound (`hi` if `code` bit 0, else `lo`), an inactive
/// variable's `w = unc - out[q]` (saturated, `out` read in order); among
/// the inactive ones with `w > hi` (violation `w - hi`, side 1) or `w <
/// lo` (`lo - w`, side 0), saturated, the first strictly largest
/// violation above `tol` wins. Returns `(index, side | 2 if lo == hi)`,
/// index `0xFF` for none.
///
/// # Safety
/// `var` must point to `n` (1..=8) writable records, `out` to as many
/// readable `i32` as there are inactive variables.
#[inline(never)]
pub(super) unsafe fn scan_avr(var: *mut u8, n: u8, out: *const i32, tol: i32) -> (u8, u8) {
    let (best, code): (u8, u8);
    let [w0, w1, w2, w3] = tol.to_le_bytes();
    // SAFETY: reads and writes the n records, reads one i32 per inactive
    // variable (the caller's contract); register-only otherwise.
    unsafe {
        core::arch::asm!(
            "ldi {best}, 0xFF",
            "clr {code}",
            "clr {j}",
            "1:",
            "ldd {t}, Z+20",
            "tst {t}",
            "breq 2f",
            // A member: exactly on its bound.
            "ldd {t}, Z+21",
            "sbrc {t}, 0",
            "rjmp 5f",
            "ldd {v0}, Z+4",
            "ldd {v1}, Z+5",
            "ldd {v2}, Z+6",
            "ldd {v3}, Z+7",
            "rjmp 6f",
            "5:",
            "ldd {v0}, Z+8",
            "ldd {v1}, Z+9",
            "ldd {v2}, Z+10",
            "ldd {v3}, Z+11",
            "6:",
            "std Z+12, {v0}",
            "std Z+13, {v1}",
            "std Z+14, {v2}",
            "std Z+15, {v3}",
            "ldd {v0}, Z+16",
            "ldd {v1}, Z+17",
            "ldd {v2}, Z+18",
            "ldd {v3}, Z+19",
            "std Z+22, {v0}",
            "std Z+23, {v1}",
            "std Z+24, {v2}",
            "std Z+25, {v3}",
            "rjmp 9f",
            "2:",
            // v = unc - out[q], saturated.
            "ld {v0}, Z",
            "ldd {v1}, Z+1",
            "ldd {v2}, Z+2",
            "ldd {v3}, Z+3",
            "ld {b0}, X+",
            "ld {b1}, X+",
            "ld {b2}, X+",
            "ld {b3}, X+",
            "sub {v0}, {b0}",
            "sbc {v1}, {b1}",
            "sbc {v2}, {b2}",
            "sbc {v3}, {b3}",
            "brvc 3f",
            "lsl {v3}",
            "sbc {v0}, {v0}",
            "mov {v1}, {v0}",
            "mov {v2}, {v0}",
            "mov {v3}, {v0}",
            "subi {v3}, 0x80",
            "3:",
            "std Z+12, {v0}",
            "std Z+13, {v1}",
            "std Z+14, {v2}",
            "std Z+15, {v3}",
            // Above hi: d = v - hi (saturated), side 1.
            "ldd {b0}, Z+8",
            "ldd {b1}, Z+9",
            "ldd {b2}, Z+10",
            "ldd {b3}, Z+11",
            "cp {b0}, {v0}",
            "cpc {b1}, {v1}",
            "cpc {b2}, {v2}",
            "cpc {b3}, {v3}",
            "brge 4f",
            "mov {d0}, {v0}",
            "mov {d1}, {v1}",
            "mov {d2}, {v2}",
            "mov {d3}, {v3}",
            "sub {d0}, {b0}",
            "sbc {d1}, {b1}",
            "sbc {d2}, {b2}",
            "sbc {d3}, {b3}",
            "ldi {side}, 1",
            "rjmp 7f",
            "4:",
            // Below lo: d = lo - v (saturated), side 0.
            "ldd {d0}, Z+4",
            "ldd {d1}, Z+5",
            "ldd {d2}, Z+6",
            "ldd {d3}, Z+7",
            "cp {v0}, {d0}",
            "cpc {v1}, {d1}",
            "cpc {v2}, {d2}",
            "cpc {v3}, {d3}",
            "brge 9f",
            "sub {d0}, {v0}",
            "sbc {d1}, {v1}",
            "sbc {d2}, {v2}",
            "sbc {d3}, {v3}",
            "ldi {side}, 0",
            "7:",
            "brvc 8f",
            "lsl {d3}",
            "sbc {d0}, {d0}",
            "mov {d1}, {d0}",
            "mov {d2}, {d0}",
            "mov {d3}, {d0}",
            "subi {d3}, 0x80",
            "8:",
            // Strictly larger than the worst so far (first: tol)?
            "cp {w0}, {d0}",
            "cpc {w1}, {d1}",
            "cpc {w2}, {d2}",
            "cpc {w3}, {d3}",
            "brge 9f",
            "mov {w0}, {d0}",
            "mov {w1}, {d1}",
            "mov {w2}, {d2}",
            "mov {w3}, {d3}",
            "mov {best}, {j}",
            "mov {code}, {side}",
            // Equal bounds: code bit 1.
            "ldd {b0}, Z+4",
            "ldd {b1}, Z+5",
            "ldd {b2}, Z+6",
            "ldd {b3}, Z+7",
            "ldd {d0}, Z+8",
            "ldd {d1}, Z+9",
            "ldd {d2}, Z+10",
            "ldd {d3}, Z+11",
            "cp {b0}, {d0}",
            "cpc {b1}, {d1}",
            "cpc {b2}, {d2}",
            "cpc {b3}, {d3}",
            "brne 9f",
            "ori {code}, 2",
            "9:",
            "adiw r30, {size}",
            "inc {j}",
            "dec {n}",
            "breq 10f",
            "rjmp 1b",
            "10:",
            best = out(reg_upper) best,
            code = out(reg_upper) code,
            side = out(reg_upper) _,
            j = out(reg) _,
            t = out(reg) _,
            v0 = out(reg) _,
            v1 = out(reg) _,
            v2 = out(reg) _,
            v3 = out(reg_upper) _,
            b0 = out(reg) _,
            b1 = out(reg) _,
            b2 = out(reg) _,
            b3 = out(reg) _,
            d0 = out(reg) _,
            d1 = out(reg) _,
            d2 = out(reg) _,
            d3 = out(reg_upper) _,
            w0 = inout(reg) w0 => _,
            w1 = inout(reg) w1 => _,
            w2 = inout(reg) w2 => _,
            w3 = inout(reg) w3 => _,
            n = inout(reg) n => _,
            size = const VAR_SIZE,
            inout("Z") var => _,
            inout("X") out => _,
            options(nostack),
        );
    }
    (best, code)
}
