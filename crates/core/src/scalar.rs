//! The scalar trait shared by the run-time code, and a saturating fixed-point type.
//!
//! Run-time kernels (Kalman step, tree walk, fast-gradient iterations) are
//! generic over [`Scalar`], so the same code runs in `f64` on the host, in
//! `f32` on a microcontroller with (or without) an FPU, and in fixed point
//! ([`Fixed`]) where floating point is too slow.

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// The arithmetic the run-time code needs, and nothing more.
///
/// There is deliberately no division: every division of the algorithms
/// (step sizes, inverses, gains) is folded into constant tables offline.
///
/// ```
/// use kestrel_core::{Scalar, Q16};
/// fn mean_of_two<S: Scalar>(a: S, b: S) -> S {
///     (a + b) * S::from_f64(0.5)
/// }
/// assert_eq!(mean_of_two(1.0_f64, 2.0), 1.5);
/// assert_eq!(mean_of_two(Q16::from_f64(1.0), Q16::from_f64(2.0)).to_f64(), 1.5);
/// ```
pub trait Scalar:
    Copy
    + Default
    + Debug
    + PartialEq
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// Additive identity.
    const ZERO: Self;
    /// Multiplicative identity.
    const ONE: Self;
    /// Largest finite value.
    const MAX: Self;
    /// Most negative finite value.
    const MIN: Self;
    /// The spacing of representable values near one (machine epsilon for
    /// floats, one least significant bit for fixed point).
    const RESOLUTION: f64;

    /// Converts from `f64`, rounding to nearest; fixed point saturates and maps NaN to zero.
    fn from_f64(v: f64) -> Self;
    /// Converts to `f64` (exact for `f32`, `f64` and [`Fixed`]).
    fn to_f64(self) -> f64;
    /// Whether the value is finite (always true for fixed point).
    fn is_finite(self) -> bool;

    /// Converts from `f32`.
    #[inline]
    fn from_f32(v: f32) -> Self {
        Self::from_f64(v as f64)
    }
    /// Converts to `f32`.
    #[inline]
    fn to_f32(self) -> f32 {
        self.to_f64() as f32
    }
    /// Absolute value (saturating for fixed point).
    #[inline]
    fn abs(self) -> Self {
        if self < Self::ZERO { -self } else { self }
    }
    /// The smaller of two values.
    #[inline]
    fn min(self, other: Self) -> Self {
        if other < self { other } else { self }
    }
    /// The larger of two values.
    #[inline]
    fn max(self, other: Self) -> Self {
        if other > self { other } else { self }
    }
    /// Clamps to `[lo, hi]`; a NaN input stays NaN (check [`Scalar::is_finite`]).
    #[inline]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        if self < lo {
            lo
        } else if self > hi {
            hi
        } else {
            self
        }
    }
    /// `self + a * b`.
    #[inline]
    fn mul_add(self, a: Self, b: Self) -> Self {
        self + a * b
    }
    /// Inner product of two equally long slices (the shorter length is used).
    ///
    /// Fixed point overrides this with a wide accumulator and a single
    /// rounding, which is both faster and more accurate.
    #[inline]
    fn dot(a: &[Self], b: &[Self]) -> Self {
        let mut acc = Self::ZERO;
        for (x, y) in a.iter().zip(b.iter()) {
            acc = acc.mul_add(*x, *y);
        }
        acc
    }
    /// The transposed matrix-vector product on arrays,
    /// `out[i] = sum_j a[j][i] x[j]` (`out = A' x`; `A x` for a symmetric
    /// `A`), each entry accumulated exactly as [`Scalar::dot`] would
    /// accumulate column `i` with `x`.
    ///
    /// The default gathers each column and calls [`Scalar::dot`] (so a
    /// type's own dot is kept); `f32` and `f64` override it with row-wise
    /// multiply-adds and [`Fixed`] with row-wise wide accumulators, in the
    /// same order, bit-identical to the default and free of the serial
    /// dependency of a dot product (the compiler vectorises the floats).
    #[inline]
    fn tr_mat_vec<const R: usize, const C: usize>(
        a: &[[Self; C]; R],
        x: &[Self; R],
        out: &mut [Self; C],
    ) {
        for (i, o) in out.iter_mut().enumerate() {
            let col: [Self; R] = core::array::from_fn(|j| {
                a.get(j)
                    .and_then(|r| r.get(i))
                    .copied()
                    .unwrap_or(Self::ZERO)
            });
            *o = Self::dot(&col, x);
        }
    }
}

/// Row-wise `out = A' x` for floats: the same per-entry order as `dot`.
#[inline]
fn float_tr_mat_vec<S: Scalar, const R: usize, const C: usize>(
    a: &[[S; C]; R],
    x: &[S; R],
    out: &mut [S; C],
) {
    // A local accumulator (kept in registers), stored once.
    let mut acc = [S::ZERO; C];
    for (row, xj) in a.iter().zip(x.iter()) {
        for (o, aji) in acc.iter_mut().zip(row.iter()) {
            *o = o.mul_add(*aji, *xj);
        }
    }
    *out = acc;
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const MAX: Self = f64::MAX;
    const MIN: Self = f64::MIN;
    const RESOLUTION: f64 = f64::EPSILON;
    #[inline]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline]
    fn tr_mat_vec<const R: usize, const C: usize>(
        a: &[[Self; C]; R],
        x: &[Self; R],
        out: &mut [Self; C],
    ) {
        float_tr_mat_vec(a, x, out);
    }
}

impl Scalar for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const MAX: Self = f32::MAX;
    const MIN: Self = f32::MIN;
    const RESOLUTION: f64 = f32::EPSILON as f64;
    #[inline]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        v
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline]
    fn tr_mat_vec<const R: usize, const C: usize>(
        a: &[[Self; C]; R],
        x: &[Self; R],
        out: &mut [Self; C],
    ) {
        float_tr_mat_vec(a, x, out);
    }
}

/// A saturating signed fixed-point number: 32 bits with `FRAC` fraction bits.
///
/// Every operation saturates at [`Fixed::MAX`] / [`Fixed::MIN`] instead of
/// wrapping, so an overflow degrades into a clamped value rather than a sign
/// flip. Products round to nearest. [`Q16`] (Q15.16: range about ±32768,
/// resolution 1.5e-5) is the type the run-time code is tested with.
///
/// ```
/// use kestrel_core::{Scalar, Q16};
/// let big = Q16::from_f64(30000.0);
/// assert_eq!((big + big).to_f64(), Q16::MAX.to_f64()); // saturates, no wrap
/// assert_eq!((Q16::from_f64(1.5) * Q16::from_f64(-2.0)).to_f64(), -3.0);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(transparent)]
pub struct Fixed<const FRAC: u32>(pub i32);

/// Q15.16 fixed point: 16 integer bits (with sign), 16 fraction bits.
pub type Q16 = Fixed<16>;

impl<const FRAC: u32> Fixed<FRAC> {
    const CHECK: () = assert!(FRAC >= 1 && FRAC <= 30, "FRAC must be in 1..=30");
    /// The raw representation as a value: `raw / 2^FRAC`.
    #[inline]
    pub const fn from_bits(raw: i32) -> Self {
        Fixed(raw)
    }
    /// The raw two's-complement bits.
    #[inline]
    pub const fn to_bits(self) -> i32 {
        self.0
    }
    #[inline]
    fn sat_from_i64(v: i64) -> Self {
        if v > i32::MAX as i64 {
            Fixed(i32::MAX)
        } else if v < i32::MIN as i64 {
            Fixed(i32::MIN)
        } else {
            Fixed(v as i32)
        }
    }
    /// Rounds a product (or sum of products) with `2 * FRAC` fraction bits back to `FRAC`.
    #[inline]
    fn round_wide(acc: i64) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        let half = 1_i64 << (FRAC - 1);
        Self::sat_from_i64(acc.saturating_add(half) >> FRAC)
    }
}

impl<const FRAC: u32> Add for Fixed<FRAC> {
    type Output = Self;
    #[inline]
    fn add(self, rhs: Self) -> Self {
        Fixed(self.0.saturating_add(rhs.0))
    }
}
impl<const FRAC: u32> Sub for Fixed<FRAC> {
    type Output = Self;
    #[inline]
    fn sub(self, rhs: Self) -> Self {
        Fixed(self.0.saturating_sub(rhs.0))
    }
}
impl<const FRAC: u32> Mul for Fixed<FRAC> {
    type Output = Self;
    #[inline]
    fn mul(self, rhs: Self) -> Self {
        Self::round_wide(self.0 as i64 * rhs.0 as i64)
    }
}
impl<const FRAC: u32> Neg for Fixed<FRAC> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Fixed(self.0.saturating_neg())
    }
}
impl<const FRAC: u32> AddAssign for Fixed<FRAC> {
    #[inline]
    fn add_assign(&mut self, rhs: Self) {
        *self = *self + rhs;
    }
}
impl<const FRAC: u32> SubAssign for Fixed<FRAC> {
    #[inline]
    fn sub_assign(&mut self, rhs: Self) {
        *self = *self - rhs;
    }
}
impl<const FRAC: u32> MulAssign for Fixed<FRAC> {
    #[inline]
    fn mul_assign(&mut self, rhs: Self) {
        *self = *self * rhs;
    }
}

impl<const FRAC: u32> Scalar for Fixed<FRAC> {
    const ZERO: Self = Fixed(0);
    const ONE: Self = Fixed(1 << FRAC);
    const MAX: Self = Fixed(i32::MAX);
    const MIN: Self = Fixed(i32::MIN);
    const RESOLUTION: f64 = 1.0 / (1u64 << FRAC) as f64;

    #[inline]
    fn from_f64(v: f64) -> Self {
        let scaled = v * (1u64 << FRAC) as f64;
        if scaled.is_nan() {
            Fixed(0)
        } else if scaled >= i32::MAX as f64 {
            Fixed(i32::MAX)
        } else if scaled <= i32::MIN as f64 {
            Fixed(i32::MIN)
        } else {
            // Round half away from zero without `f64::round` (not in core).
            let r = if scaled >= 0.0 {
                scaled + 0.5
            } else {
                scaled - 0.5
            };
            Fixed(r as i32)
        }
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self.0 as f64 / (1u64 << FRAC) as f64
    }
    #[inline]
    fn is_finite(self) -> bool {
        true
    }
    #[inline]
    fn mul_add(self, a: Self, b: Self) -> Self {
        self + a * b
    }
    #[inline]
    fn dot(a: &[Self], b: &[Self]) -> Self {
        let mut acc: i64 = 0;
        for (x, y) in a.iter().zip(b.iter()) {
            acc = acc.saturating_add(x.0 as i64 * y.0 as i64);
        }
        Self::round_wide(acc)
    }
    /// Row-wise wide accumulators, each summed in the order of
    /// [`Scalar::dot`] over its column and rounded once: bit-identical.
    #[inline]
    fn tr_mat_vec<const R: usize, const C: usize>(
        a: &[[Self; C]; R],
        x: &[Self; R],
        out: &mut [Self; C],
    ) {
        let mut acc = [0i64; C];
        for (row, xj) in a.iter().zip(x.iter()) {
            for (o, aji) in acc.iter_mut().zip(row.iter()) {
                *o = o.saturating_add(aji.0 as i64 * xj.0 as i64);
            }
        }
        for (o, v) in out.iter_mut().zip(acc.iter()) {
            *o = Self::round_wide(*v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// `tr_mat_vec` is `A' x` and bit-identical to dotting each column
    /// (the default), for floats and fixed point.
    #[test]
    fn tr_mat_vec_matches_column_dots() {
        fn check<S: Scalar + core::fmt::Debug>() {
            let a: [[S; 3]; 2] = [
                [S::from_f64(0.1), S::from_f64(-2.5), S::from_f64(3.3)],
                [S::from_f64(1.7), S::from_f64(0.4), S::from_f64(-0.9)],
            ];
            let x = [S::from_f64(1.3), S::from_f64(-0.7)];
            let mut out = [S::ZERO; 3];
            S::tr_mat_vec(&a, &x, &mut out);
            for (i, o) in out.iter().enumerate() {
                let col = [a[0][i], a[1][i]];
                assert_eq!(*o, S::dot(&col, &x));
                let exact = a[0][i].to_f64() * x[0].to_f64() + a[1][i].to_f64() * x[1].to_f64();
                assert!((o.to_f64() - exact).abs() < 1e-4, "{o:?} vs {exact}");
            }
        }
        check::<f64>();
        check::<f32>();
        check::<Q16>();
    }

    #[test]
    fn constants() {
        assert_eq!(Q16::ONE.to_f64(), 1.0);
        assert_eq!(Q16::ZERO.to_f64(), 0.0);
        assert_eq!(Q16::RESOLUTION, 1.0 / 65536.0);
        assert_eq!(<f32 as Scalar>::ONE, 1.0);
    }

    #[test]
    fn fixed_conversion_saturates_and_maps_nan_to_zero() {
        assert_eq!(Q16::from_f64(1e9), Q16::MAX);
        assert_eq!(Q16::from_f64(-1e9), Q16::MIN);
        assert_eq!(Q16::from_f64(f64::NAN), Q16::ZERO);
        assert_eq!(Q16::from_f64(f64::INFINITY), Q16::MAX);
        assert_eq!(Q16::from_f64(-0.25).to_f64(), -0.25);
    }

    #[test]
    fn fixed_saturates_instead_of_wrapping() {
        let big = Q16::from_f64(20000.0);
        assert_eq!(big + big, Q16::MAX);
        assert_eq!(-big - big, Q16::MIN);
        assert_eq!(big * big, Q16::MAX);
        assert_eq!(big * -big, Q16::MIN);
        assert_eq!(-Q16::MIN, Q16::MAX);
        assert_eq!(Q16::MIN.abs(), Q16::MAX);
        let v = [big; 4];
        assert_eq!(Q16::dot(&v, &v), Q16::MAX);
    }

    #[test]
    fn float_helpers() {
        assert_eq!(3.0_f64.clamp(0.0, 1.0), 1.0);
        assert_eq!(Scalar::abs(-2.0_f32), 2.0);
        assert_eq!(Scalar::min(1.0_f64, 2.0), 1.0);
        assert_eq!(Scalar::max(1.0_f64, 2.0), 2.0);
        assert!(!Scalar::is_finite(f32::NAN));
        assert_eq!(f64::dot(&[1.0, 2.0, 3.0], &[4.0, 5.0, 6.0]), 32.0);
    }

    proptest! {
        #[test]
        fn fixed_round_trip_within_half_lsb(v in -30000.0f64..30000.0) {
            let q = Q16::from_f64(v);
            prop_assert!((q.to_f64() - v).abs() <= 0.5 * Q16::RESOLUTION + 1e-12);
        }

        #[test]
        fn fixed_ops_match_f64_within_rounding(a in -150.0f64..150.0, b in -150.0f64..150.0) {
            let (qa, qb) = (Q16::from_f64(a), Q16::from_f64(b));
            let (fa, fb) = (qa.to_f64(), qb.to_f64());
            let lsb = Q16::RESOLUTION;
            prop_assert_eq!((qa + qb).to_f64(), fa + fb);
            prop_assert_eq!((qa - qb).to_f64(), fa - fb);
            prop_assert!(((qa * qb).to_f64() - fa * fb).abs() <= 0.5 * lsb + 1e-12);
        }

        #[test]
        fn fixed_ops_saturate_like_clamped_f64(a in -40000.0f64..40000.0, b in -40000.0f64..40000.0) {
            let (qa, qb) = (Q16::from_f64(a), Q16::from_f64(b));
            let (fa, fb) = (qa.to_f64(), qb.to_f64());
            let clamp = |x: f64| x.clamp(Q16::MIN.to_f64(), Q16::MAX.to_f64());
            prop_assert_eq!((qa + qb).to_f64(), clamp(fa + fb));
            prop_assert_eq!((qa - qb).to_f64(), clamp(fa - fb));
            prop_assert!(((qa * qb).to_f64() - clamp(fa * fb)).abs() <= Q16::RESOLUTION);
        }

        #[test]
        fn fixed_dot_rounds_once(xs in proptest::collection::vec((-10.0f64..10.0, -10.0f64..10.0), 0..12)) {
            let a: std::vec::Vec<Q16> = xs.iter().map(|p| Q16::from_f64(p.0)).collect();
            let b: std::vec::Vec<Q16> = xs.iter().map(|p| Q16::from_f64(p.1)).collect();
            let exact: f64 = a.iter().zip(&b).map(|(x, y)| x.to_f64() * y.to_f64()).sum();
            prop_assert!((Q16::dot(&a, &b).to_f64() - exact).abs() <= 0.5 * Q16::RESOLUTION + 1e-12);
        }
    }
}
