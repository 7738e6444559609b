//! Unit tests of the pipeline's pieces that need no flights.

use super::error::PipelineError;
use super::explicit::clip;
use super::sample::{BoxSampler, qp_cost};
use super::{Stage, result::PipelineResult};
use kestrel_core::formats::MpqpProblem;

fn area(p: &[(f64, f64)]) -> f64 {
    (0..p.len())
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum::<f64>()
        / 2.0
}

#[test]
fn clipping_cuts_a_square_by_half_planes() {
    let square = vec![(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)];
    // x <= 1 keeps the left half.
    let left = clip(&square, (1.0, 0.0), 1.0);
    assert!((area(&left) - 2.0).abs() < 1e-12, "{left:?}");
    // x + y <= 2 keeps the lower-left triangle.
    let tri = clip(&square, (1.0, 1.0), 2.0);
    assert!((area(&tri) - 2.0).abs() < 1e-12, "{tri:?}");
    // A half-plane that misses the square removes all of it; one that
    // contains it keeps it.
    assert!(clip(&square, (1.0, 0.0), -1.0).is_empty());
    assert_eq!(clip(&square, (1.0, 0.0), 5.0), square);
}

#[test]
fn configuration_errors_name_their_key() {
    for (message, key) in [
        ("mpc.larger: blocks [1] must add up", "mpc.larger"),
        ("kalman.flight = 7: expected 1..=4", "kalman.flight"),
        ("empc.slice_range[1]: expected", "empc.slice_range"),
        (
            "fgm.check_points = 0: expected at least 1",
            "fgm.check_points",
        ),
    ] {
        match PipelineError::config_message(message.into()) {
            PipelineError::Config { key: k, message: m } => {
                assert_eq!((k.as_str(), m.as_str()), (key, message));
            }
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn stages_are_in_the_reports_order() {
    let titles: Vec<&str> = Stage::ALL.iter().map(|s| s.title()).collect();
    for (k, t) in titles.iter().enumerate() {
        assert!(t.starts_with(&format!("{}. ", k + 1)), "{t}");
    }
    assert!(Stage::Kalman < Stage::Problems);
    // The result type is what `run` returns (a compile-time check).
    let _: fn(&super::Config, Option<Vec<super::Flight>>) -> Result<PipelineResult, PipelineError> =
        super::run;
}

#[test]
fn sampled_parameters_stay_in_the_box_and_repeat() {
    let p = MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1", "H": [[2.0]], "F": [[1.0], [0.5]], "f": [0.0],
            "G": [[1.0], [-1.0]], "W": [1.0, 1.0], "E": [[0.0, 0.0], [0.0, 0.0]],
            "theta_lb": [-1.0, 10.0], "theta_ub": [1.0, 20.0]}"#,
    )
    .unwrap();
    let (mut a, mut b) = (BoxSampler::new(7), BoxSampler::new(7));
    // The report's check points: the hand-written SplitMix64 stream (state
    // = seed, (next >> 11) / 2^53) that the sampler had before it used
    // rand_xoshiro's, scaled to the box (values from splitmix64.c).
    let first = [
        [-0.22034050321745702, 10.167882945281562],
        [0.8015213612137668, 15.82930293028078],
    ];
    for point in first {
        let t = a.theta(&p);
        assert_eq!(t.as_slice(), &point);
        assert_eq!(t, b.theta(&p));
    }
    for _ in 0..100 {
        let t = a.theta(&p);
        assert_eq!(t, b.theta(&p));
        assert!((-1.0..=1.0).contains(&t[0]) && (10.0..=20.0).contains(&t[1]));
        // 1/2 z'Hz + (F'theta)'z at z = 1.
        let z = nalgebra::DVector::from_element(1, 1.0);
        assert!((qp_cost(&p, &z, &t) - (1.0 + t[0] + 0.5 * t[1])).abs() < 1e-12);
    }
}
