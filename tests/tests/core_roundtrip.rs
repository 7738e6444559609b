//! A continuous model read from `kestrel.ss.v1`, discretised, moved into
//! the const-generic run-time type and stepped in three scalars, against
//! the exact solution of the continuous system.

use kestrel_core::formats::SsModel;
use kestrel_core::{Q16, Scalar, StateSpace};

#[test]
fn discretised_mass_spring_matches_exact_response_in_every_scalar() {
    // x'' = -w^2 x + u: with u = 0 from x(0) = 1, x(t) = cos(w t).
    let w = 3.0_f64;
    let text = format!(
        r#"{{"format": "kestrel.ss.v1", "ts": 0,
           "A": [[0, 1], [{}, 0]], "B": [[0], [1]], "C": [[1, 0]], "D": [[0]]}}"#,
        -w * w
    );
    let cont = SsModel::from_json_str(&text).unwrap();
    let disc = cont.c2d(0.02).unwrap();
    let m64 = StateSpace::<f64, 2, 1, 1>::from_model(&disc).unwrap();
    let m32 = StateSpace::<f32, 2, 1, 1>::from_model(&disc).unwrap();
    let mq = StateSpace::<Q16, 2, 1, 1>::from_model(&disc).unwrap();
    let (mut x64, mut x32, mut xq) = ([1.0, 0.0], [1.0_f32, 0.0], [Q16::ONE, Q16::ZERO]);
    for k in 1..=100 {
        x64 = m64.step(&x64, &[0.0]);
        x32 = m32.step(&x32, &[0.0]);
        xq = mq.step(&xq, &[Q16::ZERO]);
        let exact = (w * 0.02 * k as f64).cos();
        assert!(
            (m64.output(&x64, &[0.0])[0] - exact).abs() < 1e-12,
            "f64 at step {k}"
        );
        assert!((x32[0].to_f64() - exact).abs() < 1e-5, "f32 at step {k}");
        // 100 steps of rounding of one LSB (1.5e-5) each, at most.
        assert!(
            (xq[0].to_f64() - exact).abs() < 100.0 * Q16::RESOLUTION,
            "fixed at step {k}"
        );
    }
}
