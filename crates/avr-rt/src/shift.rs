//! Shifts of `i32` by a variable amount, written for the AVR (no barrel
//! shifter): [`shr_var`] and the rounding [`round_shift32`], shared by the
//! `f32` to Q15.16 conversion (`output::RtScalar`) and the 16-bit explicit
//! MPC's output scaling (`explicit::tree16`).

/// Rounds `v / 2^s` to nearest (`s` in `0..32`).
#[inline]
pub(crate) fn round_shift32(v: i32, s: u8) -> i32 {
    if s == 0 {
        return v;
    }
    // One variable shift by `s - 1`, then a constant shift by one: the
    // AVR has no barrel shifter, so a shift by a variable amount is a loop
    // of one bit per pass; `shr_var` does it in at most five constant steps.
    let h = shr_var(v, s - 1);
    (h >> 1) + (h & 1)
}

/// `v >> s` (arithmetic, `s` in `0..32`). On the AVR (no barrel shifter;
/// LLVM lowers every multi-bit `i32` shift, constant or not, to a loop of
/// one-bit passes of about 14 cycles) whole bytes move first, then one
/// 6-cycle pass per remaining bit.
#[inline]
pub(crate) fn shr_var(v: i32, s: u8) -> i32 {
    #[cfg(target_arch = "avr")]
    {
        let [mut a0, mut a1, mut a2, mut a3] = v.to_le_bytes();
        // SAFETY: register-only arithmetic.
        unsafe {
            core::arch::asm!(
                "1:",
                "cpi {s}, 8",
                "brlo 2f",
                "mov {a0}, {a1}",
                "mov {a1}, {a2}",
                "mov {a2}, {a3}",
                "lsl {a3}",
                "sbc {a3}, {a3}",
                "subi {s}, 8",
                "rjmp 1b",
                "2:",
                "tst {s}",
                "breq 4f",
                "3:",
                "asr {a3}",
                "ror {a2}",
                "ror {a1}",
                "ror {a0}",
                "dec {s}",
                "brne 3b",
                "4:",
                s = inout(reg_upper) s & 31 => _,
                a0 = inout(reg) a0,
                a1 = inout(reg) a1,
                a2 = inout(reg) a2,
                a3 = inout(reg) a3,
                options(pure, nomem, nostack),
            );
        }
        i32::from_le_bytes([a0, a1, a2, a3])
    }
    #[cfg(not(target_arch = "avr"))]
    {
        v >> (s & 31)
    }
}

/// The portable form of [`shr_var`] (kept for the host test against it).
#[cfg(test)]
fn shr_var_steps(mut v: i32, s: u8) -> i32 {
    if s & 16 != 0 {
        v >>= 16;
    }
    if s & 8 != 0 {
        v >>= 8;
    }
    if s & 4 != 0 {
        v >>= 4;
    }
    if s & 2 != 0 {
        v >>= 2;
    }
    if s & 1 != 0 {
        v >>= 1;
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_shift_rounds_to_nearest() {
        for v in [
            -1000i32,
            -3,
            -2,
            -1,
            0,
            1,
            2,
            3,
            5,
            1000,
            i32::MAX,
            i32::MIN,
        ] {
            for s in 1..32u8 {
                // 2^s exactly: `powi` is not guaranteed exact (Miri perturbs
                // it by a few ulps, which moved -1/2 + 1/2 below zero).
                let want = (v as f64 / (1u64 << s) as f64 + 0.5).floor() as i32;
                assert_eq!(round_shift32(v, s), want, "{v} >> {s}");
                assert_eq!(shr_var(v, s), shr_var_steps(v, s), "{v} >> {s}");
            }
        }
    }
}
