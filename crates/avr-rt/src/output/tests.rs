use super::*;
use kestrel_core::Q16;
use kestrel_core::{Fixed, Scalar};
use proptest::prelude::*;

#[test]
fn failsafe_sequence() {
    let mut f = Failsafe::new();
    assert_eq!(f.on_tick(None), Decision::Safe); // nothing received yet
    assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: false });
    assert_eq!(f.on_tick(None), Decision::Hold); // one frame lost: hold
    assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: false });
    assert_eq!(f.on_tick(None), Decision::Hold);
    assert_eq!(f.on_tick(None), Decision::Safe); // two periods: failsafe
    assert_eq!(f.active(), Some(FailsafeReason::Timeout));
    assert_eq!(f.on_tick(None), Decision::Safe);
    assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: true });
    assert_eq!(f.active(), None);
    assert_eq!(f.on_tick(Some(false)), Decision::Safe); // NaN in the frame
    assert_eq!(f.active(), Some(FailsafeReason::NonFinite));
    assert_eq!(f.on_tick(None), Decision::Safe);
    assert_eq!(f.on_tick(Some(true)), Decision::Run { recovered: true });
    f.non_finite_output();
    assert_eq!(f.active(), Some(FailsafeReason::NonFinite));
    assert_eq!(f.entries, 3);
}

#[test]
fn non_finite_output_is_refused() {
    let l = PwmLimits::default();
    assert_eq!(l.saturate(&[1500.0f32, f32::NAN, 1500.0, 1500.0]), None);
    assert_eq!(l.saturate(&[f64::INFINITY, 0.0, 0.0, 0.0]), None);
    assert_eq!(
        l.saturate(&[1500.4f32, 999.0, 2600.0, 1100.0]),
        Some([1500, 1000, 2000, 1200])
    );
}

#[test]
fn fixed_conversions() {
    assert_eq!(Q16::from_f32_fast(1.5), Q16::from_f64(1.5));
    assert_eq!(Q16::from_f32_fast(f32::NAN), Q16::ZERO);
    assert_eq!(Q16::from_f32_fast(1e9), Q16::MAX);
    assert_eq!(Q16::from_f64(1499.5).to_us(), Some(1500));
    assert_eq!(Q16::from_f64(-2.6).to_us(), Some(-3));
}

#[test]
fn safe_output_is_clamped() {
    let l = PwmLimits::default();
    assert_eq!(SafeOutput::default().pwm(&l), [1000, 1000, 1000, 1500]);
    let odd = SafeOutput {
        esc: 0,
        servo: 5000,
    };
    assert_eq!(odd.pwm(&l), [1000, 1000, 1000, 1800]);
}

proptest! {
    #[test]
    fn saturated_pwm_never_leaves_limits(v in proptest::array::uniform4(-1e7f32..1e7)) {
        let l = PwmLimits::default();
        let p = l.saturate(&v).unwrap();
        for (i, w) in p.iter().enumerate() {
            if i < 3 { prop_assert!((1000..=2000).contains(w)); }
            else { prop_assert!((1200..=1800).contains(w)); }
        }
        let q = l.saturate(&v.map(|x| Q16::from_f64(x as f64))).unwrap();
        for (i, w) in q.iter().enumerate() {
            if i < 3 { prop_assert!((1000..=2000).contains(w)); }
            else { prop_assert!((1200..=1800).contains(w)); }
        }
    }

    #[test]
    fn saturate_matches_clamped_round(v in -3000.0f64..3000.0) {
        let l = PwmLimits::default();
        let p = l.saturate(&[v, v, v, v]).unwrap();
        prop_assert_eq!(p[0] as f64, v.round().clamp(1000.0, 2000.0));
        prop_assert_eq!(p[3] as f64, v.round().clamp(1200.0, 1800.0));
    }
}

#[test]
fn q16_conversions_handle_the_edges() {
    assert_eq!(f32::NAN.to_q16(), None);
    assert_eq!(f64::INFINITY.to_q16(), None);
    assert_eq!(1.0e6f32.to_q16(), Some(i32::MAX));
    assert_eq!((-1.0e6f32).to_q16(), Some(i32::MIN));
    assert_eq!(1.0e-30f32.to_q16(), Some(0));
    assert_eq!(<f32 as RtScalar>::from_q16(0), 0.0);
    assert_eq!(<f32 as RtScalar>::from_q16(-65536), -1.0);
    assert_eq!(Q16::from_f64(1.5).to_q16(), Some(98304));
    assert_eq!(<Fixed<8> as RtScalar>::from_q16(98304).0, 384);
    assert_eq!(Fixed::<20>(3 << 20).to_q16(), Some(3 << 16));
}

/// The f32 conversion is exact: `round(v 2^16)`, ties away from zero,
/// saturated (computed in f64, where `v 2^16` is exact).
fn f32_q16_reference(f: f32) -> i32 {
    let s = f as f64 * 65536.0;
    s.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32
}

#[test]
fn f32_to_q16_edges() {
    for f in [
        0.0f32,
        -0.0,
        0.5 / 65536.0,
        -0.5 / 65536.0,
        1.5 / 65536.0,
        -2.5 / 65536.0,
        0.49 / 65536.0,
        f32::MIN_POSITIVE,
        1.0e-40,
        1.0,
        -1.0,
        32767.998,
        32768.0,
        -32768.0,
        f32::MAX,
        f32::MIN,
    ] {
        assert_eq!(f.to_q16(), Some(f32_q16_reference(f)), "{f:e}");
    }
    assert_eq!(f32::INFINITY.to_q16(), None);
    assert_eq!(f32::NEG_INFINITY.to_q16(), None);
}

proptest! {
    #[test]
    fn to_q16_all_is_to_q16_of_each(bits in proptest::array::uniform4(proptest::num::u32::ANY)) {
        let v = bits.map(f32::from_bits);
        let mut all = [0i32; 4];
        let got = <f32 as RtScalar>::to_q16_all(&v, &mut all);
        let each: Option<Vec<i32>> = v.iter().map(|x| x.to_q16()).collect();
        prop_assert_eq!(got.is_some(), each.is_some());
        if let Some(each) = each {
            prop_assert_eq!(&all[..], &each[..]);
        }
        // As many as the shorter slice holds.
        let mut two = [0i32; 2];
        let _ = <f32 as RtScalar>::to_q16_all(&v, &mut two);
        let mut five = [7i32; 5];
        let _ = <f32 as RtScalar>::to_q16_all(&v, &mut five);
        prop_assert_eq!(five[4], 7);
    }

    #[test]
    fn f32_to_q16_is_exact(bits in proptest::num::u32::ANY) {
        let f = f32::from_bits(bits);
        prop_assume!(f.is_finite());
        prop_assert_eq!(f.to_q16(), Some(f32_q16_reference(f)));
    }

    #[test]
    fn q16_conversions_round_to_nearest(v in -32000.0f64..32000.0) {
        let exact = (v * 65536.0).round();
        let f = v as f32;
        let from_f32 = f.to_q16().unwrap() as f64;
        prop_assert!((from_f32 - (f as f64 * 65536.0).round()).abs() <= 1.0);
        prop_assert!((v.to_q16().unwrap() as f64 - exact).abs() <= 0.5 + 1e-9);
        let back = <f32 as RtScalar>::from_q16(exact as i32) as f64;
        prop_assert!((back - exact / 65536.0).abs() <= 1e-7 * v.abs().max(1.0));
    }
}
