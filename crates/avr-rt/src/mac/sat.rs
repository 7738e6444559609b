//! [`add_sat_i32`] and [`sub_sat_i32`]: saturating `i32` sums, in assembly
//! on the AVR.

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
