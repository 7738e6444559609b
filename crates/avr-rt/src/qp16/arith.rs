//! The integer arithmetic of the kernel: exact sums of 32 x 32-bit
//! products rounded once ([`mac_round`]), reciprocals of pivots and
//! fractions by shift-and-subtract division ([`Recip`], [`frac30`]).
//!
//! Every result is defined by integer arithmetic alone (the exact sum,
//! round half up, saturation to `i32`), so the AVR and the host compute
//! the same bits: on the AVR the sum, its rounding shift and saturation
//! are one assembly routine (16 hardware multiplies per term), elsewhere
//! `i128` arithmetic (a variable 64-bit shift alone is a library call of
//! about 600 cycles on the AVR).

/// `round(sum a[i] b[i] / 2^shift)` of the exact sum, ties up, saturated
/// to `i32`; `shift` clamped to `16..=46`. On the AVR one assembly routine
/// (about 150 cycles per term); elsewhere `i128` arithmetic.
#[inline]
pub fn mac_round(a: &[i32], b: &[i32], shift: u8) -> i32 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0;
    }
    let shift = shift.clamp(16, 46);
    #[cfg(target_arch = "avr")]
    if (1..=255).contains(&n) {
        // SAFETY: both slices hold at least `n` (1..=255) elements; 16 <= shift <= 46.
        return unsafe { super::avr::mac_round_avr(a.as_ptr(), b.as_ptr(), n as u8, shift) };
    }
    let mut acc: i128 = 0;
    for (x, y) in a.iter().zip(b.iter()).take(n) {
        acc += *x as i128 * *y as i128;
    }
    // floor(acc / 2^(s-1)), then the last bit rounds up (no overflow).
    let q = acc >> (shift - 1);
    let r = (q >> 1) + (q & 1);
    r.clamp(i32::MIN as i128, i32::MAX as i128) as i32
}

/// `out[i] = round(sum_j data[i k + j] r[j] / 2^shift)` for the `out.len()`
/// rows of `k = r.len()` terms (ties up, saturated to `i32`), each sum taken
/// modulo `2^64` (exact for the kernel's tables: `|sum| < 2^63`); `shift`
/// clamped to `16..=46`. On the AVR all rows in one assembly call.
pub fn rows_round(data: &[i32], r: &[i32], shift: u8, out: &mut [i32]) {
    let k = r.len();
    let rows = out.len();
    let shift = shift.clamp(16, 46);
    if k == 0 || data.len() < rows * k {
        out.fill(0);
        return;
    }
    #[cfg(target_arch = "avr")]
    if k <= 63 && (1..=255).contains(&rows) {
        // SAFETY: `data` holds rows k elements, `r` k (1..=63), `out` rows;
        // 16 <= shift <= 46.
        unsafe {
            super::avr::rows_round_avr(
                data.as_ptr(),
                rows as u8,
                k as u8,
                r.as_ptr(),
                shift,
                out.as_mut_ptr(),
            )
        };
        return;
    }
    for (o, row) in out.iter_mut().zip(data.chunks_exact(k)) {
        let mut acc: i128 = 0;
        for (x, y) in row.iter().zip(r) {
            acc += *x as i128 * *y as i128;
        }
        let acc = acc as i64 as i128; // modulo 2^64
        let q = acc >> (shift - 1);
        let v = (q >> 1) + (q & 1);
        *o = v.clamp(i32::MIN as i128, i32::MAX as i128) as i32;
    }
}

/// `round(a b / 2^shift)` ([`mac_round`] of one term).
#[inline]
pub fn mul_round(a: i32, b: i32, shift: u8) -> i32 {
    mac_round(&[a], &[b], shift)
}

/// `floor(num 2^bits / den)` for `num <= den`, `0 < den < 2^31`, `bits
/// <= 30` (shift and subtract: no library division).
fn frac(num: u32, den: u32, bits: u8) -> u32 {
    if num >= den {
        return 1u32 << bits;
    }
    #[cfg(target_arch = "avr")]
    if bits > 0 {
        return super::avr::frac_avr(num, den, bits);
    }
    let (mut r, mut q) = (num, 0u32);
    for _ in 0..bits {
        r <<= 1;
        q <<= 1;
        if r >= den {
            r -= den;
            q |= 1;
        }
    }
    q
}

/// `cur / (cur - star)` in Q2.30 for `cur >= 0 > star` (negative `cur`
/// taken as 0; large operands are scaled down together first): the step
/// of a blocking dual update, in `[0, 1]`.
#[inline(never)]
pub fn frac30(cur: i32, star: i32) -> i32 {
    let (mut n, mut d) = (cur.max(0) as i64, cur.max(0) as i64 - star as i64);
    while d >= 1 << 30 {
        n >>= 1;
        d >>= 1;
    }
    frac(n as u32, d.max(1) as u32, 30) as i32
}

/// The reciprocal of a positive pivot `d` (raw), normalised: `q =
/// floor(2^(b + 29) / d)` in `(2^29, 2^30]` with `b` the bit length of
/// `d`; [`Recip::div`] is then one rounded product.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Recip {
    /// The normalised reciprocal.
    pub q: i32,
    /// The bit length of `d`.
    pub b: u8,
}

impl Recip {
    /// The reciprocal of `d` (raw), `None` for a bit length below
    /// `min_bits` (a vanishing pivot).
    pub fn new(d: i32, min_bits: u8) -> Option<Recip> {
        if d <= 0 {
            return None;
        }
        // Normalise d to [2^30, 2^31) by single shifts (a variable shift is
        // a loop on the AVR anyway); b is then its bit length.
        let (mut dn, mut b) = (d as u32, 31u8);
        while dn & (1 << 30) == 0 {
            dn <<= 1;
            b -= 1;
        }
        if b < min_bits.max(1) {
            return None;
        }
        // floor(2^(b-1) 2^30 / d) = floor(2^30 2^30 / dn).
        let q = frac(1 << 30, dn, 30);
        Some(Recip { q: q as i32, b })
    }

    /// `round(x 2^k / d)` (rounded, saturated); `b + 29 - k` must lie in
    /// `16..=46` (the table builder's formats guarantee it for the pivots
    /// [`Recip::new`] accepts).
    #[inline]
    pub fn div(self, x: i32, k: u8) -> i32 {
        mul_round(x, self.q, (self.b + 29).saturating_sub(k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn reference(a: &[i32], b: &[i32], shift: u8) -> i32 {
        let s: i128 = a.iter().zip(b).map(|(x, y)| *x as i128 * *y as i128).sum();
        let r = (s + (1i128 << (shift - 1))) >> shift;
        r.clamp(i32::MIN as i128, i32::MAX as i128) as i32
    }

    #[test]
    fn corners() {
        for (a, b) in [
            (i32::MAX, i32::MAX),
            (i32::MIN, i32::MAX),
            (i32::MIN, i32::MIN),
            (-1, 1),
            (3, -5),
        ] {
            for s in [16, 20, 30, 46] {
                assert_eq!(mac_round(&[a], &[b], s), reference(&[a], &[b], s));
            }
        }
        assert_eq!(mul_round(1 << 16, 3 << 16, 16), 3 << 16);
        assert_eq!(mul_round(-(1 << 15), 1, 16), 0); // -0.5 rounds up
    }

    #[test]
    fn reciprocal_and_fraction() {
        for d in [8, 9, 1000, 65_536, 65_537, 1 << 20, 123_456_789, i32::MAX] {
            let r = Recip::new(d, 4).unwrap();
            for x in [0, 1, -1, 65_536, -987_654, 1 << 29] {
                let exact = (x as f64) * 65_536.0 / d as f64;
                if exact.abs() >= 2f64.powi(31) {
                    assert_eq!(r.div(x, 16), if x < 0 { i32::MIN } else { i32::MAX });
                    continue;
                }
                let got = r.div(x, 16) as f64;
                assert!(
                    (got - exact).abs() <= 1.0 + exact.abs() * 2e-9,
                    "{x}/{d}: {got} vs {exact}"
                );
            }
        }
        assert_eq!(Recip::new(7, 4), None);
        assert_eq!(Recip::new(0, 1), None);
        assert_eq!(frac30(1, -1), 1 << 29);
        assert_eq!(frac30(0, -5), 0);
        assert_eq!(frac30(5, 0), 1 << 30);
        assert!(((1 << 29) - frac30(i32::MAX, -i32::MAX)).abs() <= 4);
    }

    proptest! {
        #[test]
        fn rows_are_rounded_sums(
            v in proptest::collection::vec(-(1i32 << 30)..(1 << 30), 1..40),
            k in 1usize..5,
            s in 16u8..=46,
        ) {
            let r: Vec<i32> = v.iter().take(k).copied().collect();
            let rows = v.len() / r.len();
            let mut out = vec![0; rows];
            rows_round(&v, &r, s, &mut out);
            for (i, o) in out.iter().enumerate() {
                prop_assert_eq!(*o, reference(&v[i * r.len()..(i + 1) * r.len()], &r, s));
            }
        }

        #[test]
        fn mac_is_the_rounded_exact_sum(
            v in proptest::collection::vec((any::<i32>(), any::<i32>()), 0..40),
            s in 16u8..=46,
        ) {
            let (a, b): (Vec<i32>, Vec<i32>) = v.into_iter().unzip();
            prop_assert_eq!(mac_round(&a, &b, s), reference(&a, &b, s));
        }
    }
}
