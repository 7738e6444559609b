//! Bad problems give clear error values, never a panic or a silent answer:
//! unbounded parameter sets, indefinite or singular H, empty feasible sets,
//! feasible sets without interior, non-finite data and bad settings.

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::{
    EmpcError, Outputs, Settings, TreeSettings, brute_force_active_sets, build_controller, solve,
};

/// min 1/2 |z|^2 + theta'z on the box |z_i| <= 1, theta in [-3, 3]^2.
fn box2() -> MpqpProblem {
    MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1",
        "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
        "G": [[1, 0], [0, 1], [-1, 0], [0, -1]], "W": [1, 1, 1, 1],
        "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
        "theta_lb": [-3, -3], "theta_ub": [3, 3]}"#,
    )
    .unwrap()
}

fn err(p: &MpqpProblem) -> EmpcError {
    solve(p, &Settings::default()).expect_err("the solve must fail")
}

#[test]
fn unbounded_parameter_sets() {
    let mut p = box2();
    p.theta_ub[1] = f64::INFINITY;
    let e = err(&p);
    assert!(matches!(e, EmpcError::UnboundedParameterSet(_)), "{e}");
    assert!(e.to_string().contains("theta_ub[1]"), "{e}");
    let mut p = box2();
    p.theta_lb[0] = -1e13;
    let e = err(&p);
    assert!(matches!(e, EmpcError::UnboundedParameterSet(_)), "{e}");
    assert!(e.to_string().contains("unbounded"), "{e}");
    // The brute-force enumeration checks the same.
    assert!(matches!(
        brute_force_active_sets(&p, &Settings::default()),
        Err(EmpcError::UnboundedParameterSet(_))
    ));
}

#[test]
fn indefinite_and_singular_hessians() {
    let mut p = box2();
    p.h[(1, 1)] = -1.0;
    let e = err(&p);
    assert!(matches!(e, EmpcError::IndefiniteHessian { .. }), "{e}");
    assert!(e.to_string().contains("not positive definite"), "{e}");
    let mut p = box2();
    p.h[(1, 1)] = 0.0; // positive semidefinite: not strictly convex
    assert!(matches!(err(&p), EmpcError::IndefiniteHessian { .. }));
    let mut p = box2();
    p.h[(0, 1)] = 0.5; // not symmetric
    let e = err(&p);
    assert!(
        matches!(
            e,
            EmpcError::Format(_) | EmpcError::IndefiniteHessian { .. }
        ),
        "{e}"
    );
}

#[test]
fn empty_feasible_sets() {
    // z_0 <= -2 and z_0 >= -1: no z for any theta.
    let mut p = box2();
    p.w[0] = -2.0;
    let e = err(&p);
    assert!(matches!(e, EmpcError::EmptyFeasibleSet), "{e}");
    assert!(e.to_string().contains("feasible set is empty"), "{e}");
    // Feasible only for theta_0 >= 5, outside the box [-3, 3].
    let mut p = box2();
    p.w[0] = -6.0;
    p.e[(0, 0)] = 1.0; // -1 <= z_0 <= -6 + theta_0 needs theta_0 >= 5
    assert!(matches!(err(&p), EmpcError::EmptyFeasibleSet));
}

#[test]
fn feasible_set_without_interior() {
    // -1 <= z_0 <= -1 + (theta_0 - 3): feasible only on the face theta_0 = 3.
    let mut p = box2();
    p.w[0] = -4.0;
    p.e[(0, 0)] = 1.0;
    let e = err(&p);
    assert!(matches!(e, EmpcError::NoInterior { .. }), "{e}");
}

#[test]
fn non_finite_data_and_bad_settings() {
    let mut p = box2();
    p.g[(1, 1)] = f64::NAN;
    let e = err(&p);
    assert!(matches!(e, EmpcError::Format(_)), "{e}");
    let s = Settings {
        radius_tol: -1.0,
        ..Settings::default()
    };
    assert!(matches!(
        solve(&box2(), &s),
        Err(EmpcError::InvalidArgument(_))
    ));
    let s = Settings {
        max_regions: 3,
        ..Settings::default()
    };
    assert!(matches!(
        solve(&box2(), &s),
        Err(EmpcError::TooManyRegions(3))
    ));
    // A tree for more outputs than variables, or for another problem.
    let p = box2();
    let sol = solve(&p, &Settings::default()).unwrap();
    let t = TreeSettings {
        outputs: Outputs::First(3),
        ..TreeSettings::default()
    };
    assert!(matches!(
        build_controller(&p, &sol, &t),
        Err(EmpcError::InvalidArgument(_))
    ));
}
