//! Transmission zeros: a reported zero is one where the Rosenbrock matrix
//! `[[A - zI, B], [C, D]]` really loses rank (issue 20, finding 5), checked
//! on the identified black-box tricopter model and on systems whose zeros
//! are known exactly.

use kestrel_core::formats::SsModel;
use kestrel_sysid::{InnovationModel, is_transmission_zero, transmission_zeros};
use nalgebra::{Complex, DMatrix};
use std::path::Path;

/// The 5-state black-box model (inputs pwm1..3, servo; outputs p, q, r),
/// a copy of `crates/tricopter/data/tricopter-blackbox-5.json`.
fn blackbox() -> InnovationModel {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tricopter-blackbox-5.json");
    InnovationModel::from_ss_model(&SsModel::read(&p).unwrap()).unwrap()
}

fn model(a: DMatrix<f64>, b: DMatrix<f64>, c: DMatrix<f64>, d: DMatrix<f64>) -> InnovationModel {
    let k = DMatrix::zeros(a.nrows(), c.nrows());
    InnovationModel::new(1.0, a, b, c, d, k).unwrap()
}

fn re(x: f64) -> Complex<f64> {
    Complex::new(x, 0.0)
}

/// The zeros as sorted real parts (all test systems have real zeros).
fn real_zeros(m: &InnovationModel) -> Vec<f64> {
    let mut z: Vec<f64> = transmission_zeros(m)
        .unwrap()
        .iter()
        .map(|z| {
            assert!(z.z.im.abs() < 1e-9, "{z:?}");
            z.z.re
        })
        .collect();
    z.sort_by(f64::total_cmp);
    z
}

fn assert_zeros(m: &InnovationModel, expected: &[f64]) {
    let z = real_zeros(m);
    assert_eq!(z.len(), expected.len(), "{z:?} vs {expected:?}");
    for (a, e) in z.iter().zip(expected) {
        assert!(
            (a - e).abs() <= 1e-8 * (1.0 + e.abs()),
            "{z:?} vs {expected:?}"
        );
    }
}

/// The black-box model (4 inputs, 3 outputs, D = 0) has no transmission
/// zeros, whatever units its inputs and outputs are in: before the fix,
/// PWM inputs in milliseconds instead of microseconds (B scaled by 1e-3)
/// gave zeros at 0.953 (and with C scaled by 10 also 0.350) that pass the
/// old relative 1e-7 singular-value test.
#[test]
fn blackbox_zeros_do_not_depend_on_units() {
    for sb in [1.0, 0.1, 1e-2, 1e-3, 1e3] {
        for sc in [1.0, 0.1, 10.0] {
            let mut m = blackbox();
            m.b *= sb;
            m.c *= sc;
            let z = transmission_zeros(&m).unwrap();
            assert!(z.is_empty(), "B x {sb}, C x {sc}: {z:?}");
        }
    }
}

/// The pencil of the black-box model has no rank drop at -48.807 (the
/// zero the report listed), -48 or -50, nor anywhere far out.
#[test]
fn blackbox_has_no_zero_at_large_z() {
    let m = blackbox();
    for z in [-48.807, -48.0, -50.0, 1e3, -1e4, 1e6] {
        assert!(!is_transmission_zero(&m, re(z)), "{z}");
    }
}

/// SISO in controllable form: the zeros are the numerator roots, among
/// them a large genuine one (60) and one at -48.807, which must be kept
/// whatever the scale of B and C.
#[test]
fn siso_numerator_roots_including_large_ones() {
    // (z - 0.5)(z - 0.6)(z + 0.3)(z - 0.9) = z^4 - 1.7 z^3 + 0.69 z^2 + 0.171 z - 0.081
    let den = [1.0, -1.7, 0.69, 0.171, -0.081];
    let a = DMatrix::from_fn(4, 4, |i, j| {
        if i == 0 {
            -den[j + 1]
        } else if i == j + 1 {
            1.0
        } else {
            0.0
        }
    });
    let b = DMatrix::from_row_slice(4, 1, &[1.0, 0.0, 0.0, 0.0]);
    // (z - 60)(z + 48.807)(z - 0.2) = z^3 - 11.393 z^2 - 2930.8814 z + 585.684
    let roots = [60.0, -48.807, 0.2];
    let num = [
        1.0,
        -(roots[0] + roots[1] + roots[2]),
        roots[0] * roots[1] + roots[0] * roots[2] + roots[1] * roots[2],
        -roots[0] * roots[1] * roots[2],
    ];
    for scale in [1.0, 1e-3, 1e3] {
        let c = DMatrix::from_row_slice(1, 4, &num) * scale;
        let m = model(a.clone(), b.clone() * scale, c, DMatrix::zeros(1, 1));
        assert_zeros(&m, &[-48.807, 0.2, 60.0]);
        let z = transmission_zeros(&m).unwrap();
        assert!(z[0].non_minimum_phase && z[1].non_minimum_phase && !z[2].non_minimum_phase);
        assert!(!is_transmission_zero(&m, re(-48.0)) && !is_transmission_zero(&m, re(-50.0)));
    }
    // With a feed-through: G(z) = 1 + 1/(z - 0.5) - 0.01... zero at 0.5 - 1/d.
    for d in [1.0, 1e-2, 1e-4] {
        let m = model(
            DMatrix::from_element(1, 1, 0.5),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::from_element(1, 1, d),
        );
        // 1/(z - 0.5) + d = 0 at z = 0.5 - 1/d: 1e4 for d = 1e-4, genuine.
        assert_zeros(&m, &[0.5 - 1.0 / d]);
    }
}

/// The textbook 2x2 plant `G(s) = 1/(s+2) [[s-1, 4], [4.5, 2(s-1)]]`
/// (Skogestad & Postlethwaite, Multivariable Feedback Control): each
/// element has a zero at 1, but the multivariable zero is at 4 alone. The
/// pencil does not care whether the variable is s or z.
#[test]
fn mimo_textbook_zero() {
    // G = diag(1, 2) + [-3; 4.5] [1, -4/3] / (s + 2).
    let m = model(
        DMatrix::from_element(1, 1, -2.0),
        DMatrix::from_row_slice(1, 2, &[1.0, -4.0 / 3.0]),
        DMatrix::from_row_slice(2, 1, &[-3.0, 4.5]),
        DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 2.0]),
    );
    assert_zeros(&m, &[4.0]);
    assert!(!is_transmission_zero(&m, re(1.0)));
    // Inputs and outputs in other units: the same zero.
    let mut s = m.clone();
    s.b.column_mut(0).scale_mut(1e-3);
    s.d.column_mut(0).scale_mut(1e-3);
    s.c.row_mut(1).scale_mut(1e2);
    s.d.row_mut(1).scale_mut(1e2);
    assert_zeros(&s, &[4.0]);
}

/// A non-square system with a built-in common zero: one input, two
/// outputs with the same numerator (z - 60)(z - 0.2), so both zeros are
/// zeros of the 2x1 system; a second, different numerator removes them.
#[test]
fn non_square_common_zero() {
    let den = [1.0, -0.8, -0.03, 0.09]; // (z-.5)(z-.6)(z+.3)
    let a = DMatrix::from_row_slice(
        3,
        3,
        &[-den[1], -den[2], -den[3], 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    );
    let b = DMatrix::from_row_slice(3, 1, &[1.0, 0.0, 0.0]);
    let c = DMatrix::from_row_slice(2, 3, &[1.0, -60.2, 12.0, 3.0, -180.6, 36.0]);
    let m = model(a.clone(), b.clone(), c, DMatrix::zeros(2, 1));
    assert_zeros(&m, &[0.2, 60.0]);
    // Second output (z - 0.7)(z + 2): no common zero.
    let c = DMatrix::from_row_slice(2, 3, &[1.0, -60.2, 12.0, 1.0, 1.3, -1.4]);
    let m = model(a, b, c, DMatrix::zeros(2, 1));
    assert_zeros(&m, &[]);
}
