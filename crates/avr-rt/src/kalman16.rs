//! [`Kalman16`]: the stationary Kalman step in fixed point with 16-bit
//! coefficients, for the AVR's hardware multiplier.
//!
//! The same filter as kestrel-kalman's `StationaryFilter` (no feed-through,
//! no cross term), in the form the firmware runs it:
//!
//! ```text
//! measurement update  e = y - y0 - C x,        x^ = x + M e
//! time update         x+ = x^ + (A - I) x^ + B u     (two rounded sums)
//! ```
//!
//! Every row sum is exact and rounded once; the measurement update adds
//! each rounded row of `M e` to the state before one saturation, the time
//! update saturates each rounded row and the two additions.
//!
//! States, measurements and inputs are Q15.16 (`i32`); every coefficient
//! row is an `i16` with its own binary point (`value = c / 2^shift`), chosen
//! offline so the row's largest entry uses the full 16 bits
//! ([`Row16`]). Storing `A - I` instead of `A` keeps the near-unit poles of
//! a 50 Hz rate model exact to the row's resolution. The sums are exact and
//! rounded once per row; on the AVR each table (`C`, `M`, `A - I`, `B`) is
//! one call of an assembly routine that runs all its rows
//! ([`Row16::apply_all`], [`Row16::add_all`]: 6 hardware multiplies and
//! 60 cycles per term for a value within 24 bits, 8 and 76 cycles for any
//! other, then the rounding shift, saturation and stores). A row may start at a column (`start`): with the
//! model in real Schur form `A - I` is upper quasi-triangular and the
//! time update skips the zeros.
//!
//! The estimator works in any [`RtScalar`] at its interface (f32 on the
//! f32 firmware, `Q16Mac` on the fixed-point one): measurements and inputs
//! are converted to Q15.16 on entry, the estimate back on exit.
//!
//! ```
//! use kestrel_avr_rt::kalman16::{Kalman16, Kalman16Tables, Row16};
//! use kestrel_core::StateEstimator;
//! // x+ = 0.9 x + 0.1 u, y = x, M = 0.5: one step from x = 0 with y = 1, u = 2.
//! let t = Kalman16Tables::<1, 1, 1> {
//!     c: [Row16::new([16384], 14, 0)],     // 1.0
//!     y0: [0],
//!     m: [Row16::new([16384], 15, 0)],     // 0.5
//!     a: [Row16::new([-26214], 18, 0)],    // A - I = -0.1
//!     b: [Row16::new([26214], 18, 0)],     // 0.1
//! };
//! let mut kf = Kalman16::<f32, 1, 1, 1>::new(t);
//! kf.measurement_update(&[1.0]).unwrap();
//! assert!((kf.estimate()[0] - 0.5).abs() < 1e-4);
//! kf.time_update(&[2.0]).unwrap();
//! assert!((kf.estimate()[0] - (0.9 * 0.5 + 0.2)).abs() < 1e-4);
//! ```

/// The coefficient row (defined with the kernels that apply it).
pub use crate::mac::Row16;
use crate::mac::{add_sat_i32, sat_i32, sub_sat_i32};
use crate::output::RtScalar;
use kestrel_core::{Error, StateEstimator, check_len};

/// `round(acc / 2^shift)` saturated to `i32`, ties rounded up (as
/// `kestrel_core::Q16`); shifts above 48 are taken as 48.
///
/// Written with constant shifts only (whole bytes, then 0-7 bits, picked
/// by `match`): on the AVR a variable 64-bit shift is a library call of
/// hundreds of cycles, a constant one a few register moves. Always
/// inlined, so a constant `shift` folds the dispatch away.
#[inline(always)]
pub fn round_shift(acc: i64, shift: u8) -> i32 {
    if shift == 0 {
        return sat_i32(acc);
    }
    // floor(acc / 2^(shift - 1)), then round the last bit away.
    let s1 = shift.min(48) - 1;
    let q = match s1 >> 3 {
        0 => acc,
        1 => acc >> 8,
        2 => acc >> 16,
        3 => acc >> 24,
        4 => acc >> 32,
        _ => acc >> 40,
    };
    let v = match s1 & 7 {
        0 => q,
        1 => q >> 1,
        2 => q >> 2,
        3 => q >> 3,
        4 => q >> 4,
        5 => q >> 5,
        6 => q >> 6,
        _ => q >> 7,
    };
    sat_i32((v >> 1) + (v & 1))
}

/// `round(v b / 2^15)` for a Q15.16 `v` and a Q1.15 `b`, saturated: two
/// 16 x 16-bit hardware products instead of a 64-bit multiply (equal to
/// the one-term row `row_q16_i16(&[v], &[b], 15)`).
#[inline]
pub fn mul_q15(v: i32, b: i16) -> i32 {
    let hi = (v >> 16) as i16 as i32;
    let lo = v & 0xFFFF;
    let b = b as i32;
    let p_hi = hi * b; // |.| <= 2^30
    let p_lo = lo * b; // |.| < 2^31
    sat_i32(2 * p_hi as i64 + ((p_lo as i64 + (1 << 14)) >> 15))
}

/// The filter's tables (`NX` states, `NU` inputs, `NY` outputs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Kalman16Tables<const NX: usize, const NU: usize, const NY: usize> {
    /// Output matrix rows.
    pub c: [Row16<NX>; NY],
    /// Output offset (Q15.16).
    pub y0: [i32; NY],
    /// Measurement-update gain rows.
    pub m: [Row16<NY>; NX],
    /// `A - I` rows.
    pub a: [Row16<NX>; NX],
    /// Input matrix rows.
    pub b: [Row16<NU>; NX],
}

impl<const NX: usize, const NU: usize, const NY: usize> Kalman16Tables<NX, NU, NY> {
    /// Multiply-adds per step (measurement and time update).
    pub fn multiply_adds(&self) -> usize {
        let n = |s: u8, len: usize| len.saturating_sub(s as usize);
        self.c.iter().map(|r| n(r.start, NX)).sum::<usize>()
            + self.m.iter().map(|r| n(r.start, NY)).sum::<usize>()
            + self.a.iter().map(|r| n(r.start, NX)).sum::<usize>()
            + self.b.iter().map(|r| n(r.start, NU)).sum::<usize>()
    }

    /// Checks the row shifts (all at most 40).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] otherwise.
    pub fn check(&self) -> Result<(), Error> {
        let ok = self.a.iter().all(|r| r.shift <= 40)
            && self.b.iter().all(|r| r.shift <= 40)
            && self.c.iter().all(|r| r.shift <= 40)
            && self.m.iter().all(|r| r.shift <= 40);
        if ok {
            Ok(())
        } else {
            Err(Error::InvalidArgument(
                "Kalman16 tables: a row shift above 40",
            ))
        }
    }
}

/// The stationary Kalman filter with 16-bit coefficients (see the module
/// docs), a [`StateEstimator`] in scalar `S`.
#[derive(Clone, Debug)]
pub struct Kalman16<S, const NX: usize, const NU: usize, const NY: usize> {
    tables: Kalman16Tables<NX, NU, NY>,
    /// Predicted (after a time update) or filtered state, Q15.16.
    x: [i32; NX],
    /// The same state in `S`.
    xs: [S; NX],
}

impl<S: RtScalar, const NX: usize, const NU: usize, const NY: usize> Kalman16<S, NX, NU, NY> {
    /// A filter at `x = 0` (the operating point).
    pub fn new(tables: Kalman16Tables<NX, NU, NY>) -> Self {
        Kalman16 {
            tables,
            x: [0; NX],
            xs: [S::ZERO; NX],
        }
    }

    /// The tables.
    pub fn tables(&self) -> &Kalman16Tables<NX, NU, NY> {
        &self.tables
    }

    /// The state in Q15.16.
    pub fn state_q16(&self) -> &[i32; NX] {
        &self.x
    }

    /// Converts the state for [`StateEstimator::estimate`]; nothing to do
    /// for scalars stored as Q15.16 bits (the estimate is the state itself).
    #[inline(always)]
    fn publish(&mut self) {
        if S::from_q16_bits(&self.x).is_some() {
            return;
        }
        for (s, x) in self.xs.iter_mut().zip(self.x.iter()) {
            *s = S::from_q16(*x);
        }
    }
}

/// `e = y - y0 - C x`, `x <- x + M e` in Q15.16.
#[inline(always)]
fn measure<const NX: usize, const NU: usize, const NY: usize>(
    t: &Kalman16Tables<NX, NU, NY>,
    x: &mut [i32; NX],
    y: &[i32; NY],
) {
    let cx = Row16::apply_all(&t.c, x);
    let mut e = [0i32; NY];
    for ((ei, yi), (cxi, y0)) in e.iter_mut().zip(y.iter()).zip(cx.iter().zip(t.y0.iter())) {
        *ei = sub_sat_i32(sub_sat_i32(*yi, *y0), *cxi);
    }
    Row16::add_all(&t.m, &e, x);
}

/// `x <- x + (A - I) x + B u` in Q15.16.
#[inline(always)]
fn predict<const NX: usize, const NU: usize, const NY: usize>(
    t: &Kalman16Tables<NX, NU, NY>,
    x: &mut [i32; NX],
    u: &[i32; NU],
) {
    // Both sums from the state before the update (no copy of it), then
    // added with the assembly saturating sums.
    let ax = Row16::apply_all(&t.a, x);
    let bu = Row16::apply_all(&t.b, u);
    for ((xi, a), b) in x.iter_mut().zip(ax.iter()).zip(bu.iter()) {
        *xi = add_sat_i32(add_sat_i32(*xi, *a), *b);
    }
}

/// Runs `f` on `v` as Q15.16 bits: in place for scalars stored as those
/// bits, otherwise converted (a copy).
#[inline(always)]
fn with_q16<S: RtScalar, const N: usize>(v: &[S], f: impl FnOnce(&[i32; N])) -> Result<(), Error> {
    if let Some(bits) = S::as_q16_bits(v) {
        let bits: &[i32; N] = bits.try_into().map_err(|_| Error::DimensionMismatch {
            expected: N,
            found: v.len(),
        })?;
        f(bits);
        return Ok(());
    }
    // Converted in place into the array `f` reads (no array returned
    // through a `Result`: on the AVR that was a `memcpy`).
    check_len(v, N)?;
    let mut bits = [0i32; N];
    S::to_q16_all(v, &mut bits).ok_or(Error::NonFinite)?;
    f(&bits);
    Ok(())
}

/// `v` as Q15.16 bits, value by value in Rust (the reset: with the
/// loop's constant zero state inlined, this folds away; the assembly
/// routine of [`RtScalar::to_q16_all`] would not).
fn to_q16<S: RtScalar, const N: usize>(v: &[S]) -> Result<[i32; N], Error> {
    check_len(v, N)?;
    let mut out = [0i32; N];
    for (o, x) in out.iter_mut().zip(v.iter()) {
        *o = x.to_q16().ok_or(Error::NonFinite)?;
    }
    Ok(out)
}

impl<S: RtScalar, const NX: usize, const NU: usize, const NY: usize> StateEstimator
    for Kalman16<S, NX, NU, NY>
{
    type Scalar = S;
    fn nx(&self) -> usize {
        NX
    }
    fn nu(&self) -> usize {
        NU
    }
    fn ny(&self) -> usize {
        NY
    }
    // The updates are not inlined, so that their conversions and sums run
    // in a short stack frame of their own on the AVR (inlined into the
    // firmware's large loop, every access to a local costs several
    // instructions).
    #[inline(never)]
    fn measurement_update(&mut self, y: &[S]) -> Result<(), Error> {
        let (t, x) = (&self.tables, &mut self.x);
        with_q16(y, |y: &[i32; NY]| measure(t, x, y))?;
        self.publish();
        Ok(())
    }
    #[inline(never)]
    fn time_update(&mut self, u: &[S]) -> Result<(), Error> {
        let (t, x) = (&self.tables, &mut self.x);
        with_q16(u, |u: &[i32; NU]| predict(t, x, u))?;
        self.publish();
        Ok(())
    }
    fn estimate(&self) -> &[S] {
        S::from_q16_bits(&self.x).unwrap_or(&self.xs)
    }
    fn reset(&mut self, x0: &[S]) -> Result<(), Error> {
        self.x = to_q16(x0)?;
        self.publish();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mac::Q16Mac;

    #[test]
    fn round_shift_rounds_and_saturates() {
        assert_eq!(round_shift(5, 1), 3);
        assert_eq!(round_shift(-5, 1), -2);
        assert_eq!(round_shift(7, 0), 7);
        assert_eq!(round_shift(i64::MAX, 2), i32::MAX);
        assert_eq!(round_shift(i64::MIN, 2), i32::MIN);
        assert_eq!(round_shift(3 << 40, 40), 3);
    }

    proptest::proptest! {
        #[test]
        fn round_shift_is_the_rounded_quotient(acc in -(1i64 << 56)..(1i64 << 56), shift in 0u8..=48) {
            let exact = (acc as i128 + if shift == 0 { 0 } else { 1i128 << (shift - 1) }) >> shift;
            let want = exact.clamp(i32::MIN as i128, i32::MAX as i128) as i32;
            proptest::prop_assert_eq!(round_shift(acc, shift), want);
        }

        #[test]
        fn mul_q15_is_the_rounded_product(v in proptest::num::i32::ANY, b in proptest::num::i16::ANY) {
            let exact = ((v as i64 * b as i64) + (1 << 14)) >> 15;
            let want = exact.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            proptest::prop_assert_eq!(mul_q15(v, b), want);
        }
    }

    fn tables() -> Kalman16Tables<2, 1, 1> {
        Kalman16Tables {
            c: [Row16::new([16384, 0], 14, 0)],
            y0: [65536],
            m: [Row16::new([16384], 15, 0), Row16::new([8192], 15, 0)],
            a: [
                Row16::new([0, 20972], 20, 0),
                Row16::new([0, -20972], 22, 1),
            ],
            b: [Row16::new([0], 20, 0), Row16::new([20972], 22, 0)],
        }
    }

    /// A row in 128-bit arithmetic: the exact sum over `j >= start`,
    /// rounded half up by the row's shift, saturated.
    fn row_ref<const N: usize>(r: &Row16<N>, v: &[i32; N]) -> i32 {
        let s = r.shift.min(48) as u32;
        let sum: i128 = (r.start as usize..N)
            .map(|j| r.c[j] as i128 * v[j] as i128)
            .sum();
        let half = if s == 0 { 0 } else { 1i128 << (s - 1) };
        ((sum + half).div_euclid(1i128 << s)).clamp(i32::MIN as i128, i32::MAX as i128) as i32
    }

    /// The rounded row, not saturated.
    fn row_round<const N: usize>(r: &Row16<N>, v: &[i32; N]) -> i128 {
        let s = r.shift.min(48) as u32;
        let sum: i128 = (r.start as usize..N)
            .map(|j| r.c[j] as i128 * v[j] as i128)
            .sum();
        let half = if s == 0 { 0 } else { 1i128 << (s - 1) };
        (sum + half).div_euclid(1i128 << s)
    }

    fn sat(v: i128) -> i32 {
        v.clamp(i32::MIN as i128, i32::MAX as i128) as i32
    }

    fn arb_row<const N: usize>() -> impl proptest::strategy::Strategy<Value = Row16<N>> {
        use proptest::prelude::*;
        (
            proptest::array::uniform::<_, N>(any::<i16>()),
            0u8..=40,
            0u8..=N as u8,
        )
            .prop_map(|(c, shift, start)| Row16::new(c, shift, start))
    }

    proptest::proptest! {
        /// One step of `Kalman16` equals the same arithmetic written out in
        /// 128-bit integers, bit for bit (the sums are exact, each row is
        /// rounded once), for any tables and any (also saturating) values.
        #[test]
        fn step_is_bit_exact_against_a_128_bit_reference(
            c in proptest::array::uniform3(arb_row::<4>()),
            m in proptest::array::uniform4(arb_row::<3>()),
            a in proptest::array::uniform4(arb_row::<4>()),
            b in proptest::array::uniform4(arb_row::<2>()),
            y0 in proptest::array::uniform3(-(1i32 << 20)..(1 << 20)),
            x0 in proptest::array::uniform4(proptest::num::i32::ANY),
            y in proptest::array::uniform3(proptest::num::i32::ANY),
            u in proptest::array::uniform2(proptest::num::i32::ANY),
        ) {
            let t = Kalman16Tables::<4, 2, 3> { c, y0, m, a, b };
            let mut kf = Kalman16::<Q16Mac, 4, 2, 3>::new(t);
            kf.reset(&x0.map(Q16Mac)).unwrap();
            kf.measurement_update(&y.map(Q16Mac)).unwrap();
            // Reference measurement update.
            let e: [i32; 3] = core::array::from_fn(|i| {
                sat(sat(y[i] as i128 - y0[i] as i128) as i128 - row_ref(&c[i], &x0) as i128)
            });
            let xm: [i32; 4] =
                core::array::from_fn(|i| sat(x0[i] as i128 + row_round(&m[i], &e)));
            proptest::prop_assert_eq!(kf.state_q16(), &xm);
            kf.time_update(&u.map(Q16Mac)).unwrap();
            let xp: [i32; 4] = core::array::from_fn(|i| {
                sat(sat(xm[i] as i128 + row_ref(&a[i], &xm) as i128) as i128
                    + row_ref(&b[i], &u) as i128)
            });
            proptest::prop_assert_eq!(kf.state_q16(), &xp);
            let published: Vec<i32> = kf.estimate().iter().map(|v| v.0).collect();
            proptest::prop_assert_eq!(published, xp.to_vec());
        }
    }

    #[test]
    fn rejects_bad_input_and_tables() {
        let mut kf = Kalman16::<f64, 2, 1, 1>::new(tables());
        assert_eq!(kf.measurement_update(&[f64::NAN]), Err(Error::NonFinite));
        assert!(kf.measurement_update(&[1.0, 2.0]).is_err());
        assert_eq!(kf.time_update(&[f64::INFINITY]), Err(Error::NonFinite));
        assert!(kf.reset(&[0.0]).is_err());
        assert!(tables().check().is_ok());
        let mut bad = tables();
        bad.b[0].shift = 41;
        assert!(bad.check().is_err());
        assert_eq!(tables().multiply_adds(), 2 + 2 + 2 + 1 + 1 + 1);
        // Scalars read in place (Q15.16 bits) check the lengths too.
        let mut kq = Kalman16::<Q16Mac, 2, 1, 1>::new(tables());
        assert!(kq.measurement_update(&[Q16Mac(1), Q16Mac(2)]).is_err());
        assert!(kq.time_update(&[]).is_err());
        assert!(kq.reset(&[Q16Mac(0)]).is_err());
    }

    /// The in-place path (`Q16Mac`, `Q16`) and the converting path (`f64`)
    /// give the same state and estimate.
    #[test]
    fn in_place_and_converted_scalars_agree() {
        use kestrel_core::Q16;
        let mut kq = Kalman16::<Q16Mac, 2, 1, 1>::new(tables());
        let mut kc = Kalman16::<Q16, 2, 1, 1>::new(tables());
        let mut kf = Kalman16::<f64, 2, 1, 1>::new(tables());
        for k in 0..20 {
            let y = (k as f64 * 0.7).sin() * 3.0;
            let u = (k as f64 * 0.3).cos() * 40.0;
            let yq = Q16Mac(f64::to_q16(y).unwrap());
            let uq = Q16Mac(f64::to_q16(u).unwrap());
            kq.measurement_update(&[yq]).unwrap();
            kc.measurement_update(&[Q16::from_bits(yq.0)]).unwrap();
            kf.measurement_update(&[y]).unwrap();
            kq.time_update(&[uq]).unwrap();
            kc.time_update(&[Q16::from_bits(uq.0)]).unwrap();
            kf.time_update(&[u]).unwrap();
            assert_eq!(kq.state_q16(), kf.state_q16());
            assert_eq!(kc.state_q16(), kf.state_q16());
            let est: Vec<i32> = kq.estimate().iter().map(|v| v.0).collect();
            assert_eq!(est, kf.state_q16().to_vec());
            let est: Vec<i32> = kc.estimate().iter().map(|v| v.to_bits()).collect();
            assert_eq!(est, kf.state_q16().to_vec());
            for (e, x) in kf.estimate().iter().zip(kf.state_q16()) {
                assert_eq!(*e, *x as f64 / 65536.0);
            }
        }
        assert!(kf.state_q16().iter().any(|&x| x != 0));
    }
}
