//! [`self_test`]: the on-target check of the AVR assembly of this module
//! against plain 64-bit arithmetic and `kestrel_core::Q16`.

use super::dot16::dot_q16_i16;
use super::q16mac::Q16Mac;
use super::row::{round_shift_i64, row_q16_i16};
use super::row16::Row16;
use super::sat::{add_sat_i32, sub_sat_i32};
use crate::output::RtScalar;
use kestrel_core::{Q16, Scalar};

/// Compares [`Q16Mac`] with [`Q16`] on `n` pseudo-random products and
/// 5-element dot products, [`dot_q16_i16`] with 64-bit arithmetic, and
/// (every fourth round) [`row_q16_i16`] and the rows routine of
/// `Row16::apply_all` with 64-bit arithmetic (a linear congruential
/// sequence from `seed`, mixing small, full-range and 24-bit boundary
/// values, every shift, saturation); returns the number of mismatches.
/// The firmware runs it at boot, so the AVR assembly is checked on target.
/// Never inlined: inlined into the firmware's large `main` (which LLVM did
/// once its panic paths were gone), its locals cost several instructions
/// each and the boot took 1-2 ms longer.
#[inline(never)]
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
        let all = <f32 as RtScalar>::to_q16_all(&f, &mut fast);
        let each: Option<[i32; 4]> = (|| {
            let mut o = [0i32; 4];
            for (o, x) in o.iter_mut().zip(&f) {
                *o = RtScalar::to_q16(*x)?;
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
        let rows: [Row16<5>; 3] = core::array::from_fn(|_| {
            Row16::new(
                core::array::from_fn(|_| (next() >> 4) as i16),
                (next() as u32 % 52) as u8,
                (next() as u32 % 7) as u8,
            )
        });
        let got = Row16::apply_all(&rows, &xf);
        let mut acc: [i32; 3] = core::array::from_fn(|_| next());
        let base = acc;
        Row16::add_all(&rows, &xf, &mut acc);
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

    #[test]
    fn self_test_passes_on_the_host() {
        assert_eq!(self_test(1, 500), 0);
    }
}
