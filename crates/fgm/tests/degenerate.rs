//! Degenerate inputs get a clear error or an explicit "no bound", never a
//! panic or a saturated count (issue 20, findings 8 and 11).

use kestrel_core::formats::MpqpProblem;
use kestrel_fgm::{BoxQp, FgmDesign, FgmError, FgmSettings, Momentum, Preconditioner};

/// -1 + t <= z0 <= 1 + t, -2 <= z1 <= 2, theta = [x, t] in [-2, 2] x [0, 0.5].
const BOX: &str = r#"{"format": "kestrel.mpqp.v1",
  "H": [[4, 1], [1, 2]], "F": [[3, -1], [0, 0]],
  "G": [[0, 2], [1, 0], [0, -1], [-3, 0]], "W": [4, 1, 2, 3],
  "E": [[0, 0], [0, 1], [0, 0], [0, -3]],
  "theta_lb": [-2, 0], "theta_ub": [2, 0.5]}"#;

fn design(text: &str, momentum: Momentum) -> FgmDesign {
    let qp = BoxQp::from_mpqp(&MpqpProblem::from_json_str(text).unwrap()).unwrap();
    let settings = FgmSettings {
        preconditioner: Preconditioner::Jacobi,
        momentum,
        ..FgmSettings::default()
    };
    FgmDesign::new(qp, settings).unwrap()
}

/// An mp-QP without decision variables (`"H": []`) panicked inside
/// nalgebra when designing the solver (exit 101 from `kestrel fgm`).
#[test]
fn a_problem_without_variables_is_refused() {
    let prob = MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1", "H": [], "F": [], "G": [], "W": [], "E": [],
            "theta_lb": [], "theta_ub": []}"#,
    )
    .unwrap();
    assert_eq!(prob.n(), 0);
    let e = BoxQp::from_mpqp(&prob).unwrap_err();
    assert!(matches!(e, FgmError::Problem(_)), "{e:?}");
    assert!(e.to_string().contains("no decision variables"), "{e}");
    // The same through a hand-made BoxQp.
    let mut qp = BoxQp::from_mpqp(&MpqpProblem::from_json_str(BOX).unwrap()).unwrap();
    qp.h = nalgebra::DMatrix::zeros(0, 0);
    qp.f_theta = nalgebra::DMatrix::zeros(2, 0);
    qp.f = nalgebra::DVector::zeros(0);
    qp.lo0 = nalgebra::DVector::zeros(0);
    qp.hi0 = nalgebra::DVector::zeros(0);
    qp.lo_theta = nalgebra::DMatrix::zeros(0, 2);
    qp.hi_theta = nalgebra::DMatrix::zeros(0, 2);
    let e = FgmDesign::new(qp, FgmSettings::default()).unwrap_err();
    assert!(e.to_string().contains("no decision variables"), "{e}");
}

/// `eps = 1e-300` made the sublinear bound `2 sqrt(Delta/eps) - 2` saturate
/// to `usize::MAX` (printed as 18446744073709551615); it is now `None`
/// (beyond [`kestrel_fgm::MAX_ITERATION_BOUND`]) and the certified count is
/// the linear bound, which stays small.
#[test]
fn a_tiny_eps_gives_no_sublinear_bound_instead_of_a_saturated_one() {
    let d = design(BOX, Momentum::Auto);
    let c = d.certify(1e-300).unwrap();
    assert_eq!(c.sublinear_bound, None);
    assert_eq!(Some(c.iterations), c.linear_bound);
    assert!(c.iterations < 10_000, "{c:?}");
    // Ordinary tolerances still have both bounds.
    let c = d.certify(1e-6).unwrap();
    assert!(c.sublinear_bound.is_some() && c.linear_bound.is_some());
    assert!(c.sublinear_bound.unwrap() < kestrel_fgm::MAX_ITERATION_BOUND);
}

/// With a singular Hessian (mu = 0) only the sublinear bound exists: a
/// tolerance it cannot reach within the limit is an error, not a count.
#[test]
fn a_tiny_eps_without_strong_convexity_is_an_error() {
    let singular = BOX.replace("[[4, 1], [1, 2]]", "[[1, 1], [1, 1]]");
    let d = design(&singular, Momentum::Auto);
    let c = d.certify(1e-6).unwrap();
    assert_eq!(c.linear_bound, None);
    assert!(c.sublinear_bound.is_some());
    let e = d.certify(1e-300).unwrap_err();
    assert!(matches!(e, FgmError::NoIterationBound { .. }), "{e:?}");
    assert!(e.to_string().contains("larger eps"), "{e}");
}

/// `fgm solve` silently solved for parameters outside the certified box
/// (`empc eval` warns): the box tells which entry is outside.
#[test]
fn parameters_outside_the_box_are_found() {
    let d = design(BOX, Momentum::Auto);
    assert_eq!(d.problem.outside_parameter_box(&[0.0, 0.25]), None);
    assert_eq!(d.problem.outside_parameter_box(&[2.0, 0.5]), None);
    assert_eq!(d.problem.outside_parameter_box(&[0.0, 0.6]), Some(1));
    assert_eq!(d.problem.outside_parameter_box(&[-2.5, 0.0]), Some(0));
}

/// A parameter box of 1e300 overflowed the preconditioner's scale and was
/// reported as "H: non-finite value" although H was fine; it is a range
/// error naming the box. The scale grows with the box, so 1e100 still
/// designs.
#[test]
fn a_box_that_overflows_the_scaling_is_a_range_error() {
    for (ub, overflows) in [("1e300", true), ("1e100", false)] {
        let text = BOX.replace(
            r#""theta_ub": [2, 0.5]"#,
            &format!(r#""theta_ub": [{ub}, 0.5]"#),
        );
        let qp = BoxQp::from_mpqp(&MpqpProblem::from_json_str(&text).unwrap()).unwrap();
        let result = FgmDesign::new(qp, FgmSettings::default());
        match (result, overflows) {
            (Err(e @ FgmError::Range(_)), true) => {
                assert!(e.to_string().contains("parameter box overflow"), "{e}")
            }
            (Ok(d), false) => assert!(d.certify(1e-3).is_ok()),
            (r, _) => panic!("ub {ub}: {:?}", r.map(|_| ())),
        }
    }
}
