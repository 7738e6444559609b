//! [`Row16`]: one row of 16-bit coefficients with its own binary point, the
//! table entry of the 16-bit kernels (`kalman16`, `fgm16`), applied by
//! [`row_q16_i16`] or, for a whole table, by the AVR rows routine.

use super::dot16::dot_q16_i16;
use super::row::row_q16_i16;

/// One coefficient row: `value_j = c[j] / 2^shift` for `j >= start`
/// (entries before `start` are zero and skipped). `#[repr(C)]`: the AVR
/// rows routine walks arrays of rows in memory ([`Row16::apply_all`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Row16<const N: usize> {
    /// The coefficients.
    pub c: [i16; N],
    /// Fraction bits of the coefficients (0 to 40).
    pub shift: u8,
    /// First non-zero column.
    pub start: u8,
}

impl<const N: usize> Row16<N> {
    /// A row from its parts.
    pub const fn new(c: [i16; N], shift: u8, start: u8) -> Self {
        Row16 { c, shift, start }
    }

    /// `round(sum_j c_j v_j / 2^shift)` for Q15.16 `v`, saturated to `i32`
    /// (`round_shift(self.dot(v), self.shift)`, on the AVR in one assembly
    /// routine: [`row_q16_i16`]).
    #[inline]
    pub fn apply(&self, v: &[i32; N]) -> i32 {
        let s = (self.start as usize).min(N);
        match (v.get(s..), self.c.get(s..)) {
            (Some(v), Some(c)) => row_q16_i16(v, c, self.shift),
            _ => 0,
        }
    }

    /// Every row of `rows` applied to `v` (`out[i] = rows[i].apply(v)`),
    /// bit for bit; on the AVR all rows in one assembly routine (for
    /// `1 <= N <= 31` and at most 255 rows).
    #[inline]
    pub fn apply_all<const R: usize>(rows: &[Row16<N>; R], v: &[i32; N]) -> [i32; R] {
        #[cfg(target_arch = "avr")]
        if (1..=255).contains(&R) && (1..=31).contains(&N) {
            const {
                assert!(core::mem::size_of::<Row16<N>>() == 2 * N + 2);
            }
            let mut out = core::mem::MaybeUninit::<[i32; R]>::uninit();
            // SAFETY: `R` rows of the `#[repr(C)]` layout (size checked
            // above), `N` values, `R` outputs; 1 <= N <= 31. The routine
            // writes all `R` outputs, so `out` is initialised after it.
            unsafe {
                super::rows::rows_q16_i16_avr::<N, false>(
                    rows.as_ptr() as *const u8,
                    R as u8,
                    v.as_ptr(),
                    out.as_mut_ptr() as *mut i32,
                );
                return out.assume_init();
            }
        }
        core::array::from_fn(|i| rows.get(i).map_or(0, |r| r.apply(v)))
    }

    /// Adds every row of `rows` applied to `v` to `out`, with one
    /// saturation: `out[i] = sat(out[i] + round(sum_j c_ij v_j / 2^shift_i))`
    /// (the rounded row is not saturated on its own); on the AVR all rows
    /// in one assembly routine (for `1 <= N <= 31` and at most 255 rows).
    #[inline]
    pub fn add_all<const R: usize>(rows: &[Row16<N>; R], v: &[i32; N], out: &mut [i32; R]) {
        #[cfg(target_arch = "avr")]
        if (1..=255).contains(&R) && (1..=31).contains(&N) {
            const {
                assert!(core::mem::size_of::<Row16<N>>() == 2 * N + 2);
            }
            // SAFETY: `R` rows of the `#[repr(C)]` layout (size checked
            // above), `N` values, `R` outputs read and written; 1 <= N <= 31.
            unsafe {
                super::rows::rows_q16_i16_avr::<N, true>(
                    rows.as_ptr() as *const u8,
                    R as u8,
                    v.as_ptr(),
                    out.as_mut_ptr(),
                );
            }
            return;
        }
        for (o, r) in out.iter_mut().zip(rows.iter()) {
            let v = *o as i64 + round_i64(r.dot(v), r.shift);
            *o = sat_i32(v);
        }
    }

    /// The exact sum `sum_{j >= start} c_j v_j` (`16 + shift` fraction bits).
    #[inline]
    pub fn dot(&self, v: &[i32; N]) -> i64 {
        let s = (self.start as usize).min(N);
        match (v.get(s..), self.c.get(s..)) {
            (Some(v), Some(c)) if !v.is_empty() => dot_q16_i16(v, c),
            _ => 0,
        }
    }
}

/// `round(acc / 2^shift)`, ties up, not saturated; shifts above 48 are
/// taken as 48 (`|acc| < 2^62` in the kernels, so no overflow).
#[inline]
fn round_i64(acc: i64, shift: u8) -> i64 {
    let s = shift.min(48);
    if s == 0 {
        acc
    } else {
        let q = acc >> (s - 1);
        (q >> 1) + (q & 1)
    }
}

/// `v` saturated to `i32`.
#[inline]
pub(crate) fn sat_i32(v: i64) -> i32 {
    if v > i32::MAX as i64 {
        i32::MAX
    } else if v < i32::MIN as i64 {
        i32::MIN
    } else {
        v as i32
    }
}
