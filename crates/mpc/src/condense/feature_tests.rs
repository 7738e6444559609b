//! Tests of the general constraints and cost terms on small problems with
//! answers known in closed form (the random cross-check against an
//! independent uncondensed formulation is `tests/tests/mpc_features.rs`).

use crate::constraints::{Bounds, InputTarget, Parameter, SoftPenalty, TerminalSet};
use crate::design::{MpcSettings, Terminal, Weight};
use crate::error::MpcError;
use crate::qp::{QpSettings, ReferenceSolver};
use crate::rows::ConstraintKind;
use crate::{MpcLaw, MpcProblem};
use kestrel_core::ControlLaw;
use kestrel_core::formats::SsModel;
use nalgebra::{DMatrix, DVector, dmatrix, dvector};

/// A double integrator sampled at 0.1 s: position and velocity, force input.
fn double_integrator() -> SsModel {
    SsModel::new(
        0.1,
        dmatrix![1.0, 0.1; 0.0, 1.0],
        dmatrix![0.005; 0.1],
        dmatrix![1.0, 0.0],
        dmatrix![0.0],
    )
    .unwrap()
}

fn unit_input() -> Option<Bounds> {
    Some(Bounds::new(dvector![-1.0], dvector![1.0]))
}

#[test]
fn soft_output_bound_returns_the_least_violation_when_the_hard_one_is_infeasible() {
    // From rest at 0 the position after one step is within +-0.005 for
    // |u| <= 1, so y <= -0.5 cannot hold at step 1: the hard problem is
    // infeasible, and the soft one's slack (one per output, shared by every
    // step) is the least violation 0.5 - 0.005 when the exact penalty
    // dominates the tracking cost.
    let m = double_integrator();
    let base = MpcSettings {
        horizon: 5,
        terminal: Terminal::None,
        input_bounds: unit_input(),
        ..MpcSettings::default()
    };
    let y_max = Bounds::new(dvector![f64::NEG_INFINITY], dvector![-0.5]);
    let hard = MpcProblem::build(
        &m,
        &MpcSettings {
            output_bounds: Some(y_max.clone()),
            ..base.clone()
        },
    )
    .unwrap();
    let theta = hard.theta(&[0.0, 0.0], &[0.0]).unwrap();
    let mut qp = ReferenceSolver::new(&hard.to_mpqp(), QpSettings::default()).unwrap();
    assert!(matches!(qp.solve(&theta), Err(MpcError::Infeasible)));

    let penalty = SoftPenalty {
        quadratic: 1.0,
        linear: 1e4,
    };
    let soft = MpcProblem::build(
        &m,
        &MpcSettings {
            output_bounds: Some(y_max.with_soft(penalty)),
            ..base
        },
    )
    .unwrap();
    assert_eq!(soft.n_slack, 1);
    assert_eq!(soft.n(), 6);
    let mut qp = ReferenceSolver::new(&soft.to_mpqp(), QpSettings::default()).unwrap();
    let sol = qp.solve(&theta).unwrap();
    assert!(sol.polished);
    assert!((sol.z[5] - 0.495).abs() < 1e-9, "slack {}", sol.z[5]);
    assert!((sol.z[0] + 1.0).abs() < 1e-9, "first move {}", sol.z[0]);
}

#[test]
fn soft_bound_with_exact_penalty_equals_the_hard_solution_where_that_is_feasible() {
    let m = double_integrator();
    let base = MpcSettings {
        horizon: 8,
        q2: Weight::Scalar(0.01),
        input_bounds: unit_input(),
        ..MpcSettings::default()
    };
    let y = Bounds::new(dvector![-0.3], dvector![0.3]);
    let hard = MpcProblem::build(
        &m,
        &MpcSettings {
            output_bounds: Some(y.clone()),
            ..base.clone()
        },
    )
    .unwrap();
    let soft = MpcProblem::build(
        &m,
        &MpcSettings {
            output_bounds: Some(y.with_soft(SoftPenalty {
                quadratic: 1.0,
                linear: 1e5,
            })),
            ..base
        },
    )
    .unwrap();
    let mut qh = ReferenceSolver::new(&hard.to_mpqp(), QpSettings::default()).unwrap();
    let mut qs = ReferenceSolver::new(&soft.to_mpqp(), QpSettings::default()).unwrap();
    let mut active = 0;
    for (x, r) in [(0.0, 1.0), (0.1, 0.5), (-0.2, -2.0), (0.0, 0.2)] {
        let th = hard.theta(&[x, 0.0], &[r]).unwrap();
        let (h, s) = (qh.solve(&th).unwrap(), qs.solve(&th).unwrap());
        assert!(s.z[8].abs() < 1e-9, "slack {}", s.z[8]);
        assert!((h.z.rows(0, 8) - s.z.rows(0, 8)).amax() < 1e-8);
        active += usize::from(h.lambda.amax() > 1e-6);
    }
    assert!(
        active >= 2,
        "the output bound should be active in some cases"
    );
}

#[test]
fn the_law_keeps_its_input_moves_within_the_rate_bound() {
    let m = double_integrator();
    let s = MpcSettings {
        horizon: 10,
        q2: Weight::Scalar(0.01),
        du_weight: Some(Weight::Scalar(0.1)),
        input_bounds: unit_input(),
        du_bounds: Some(Bounds::new(dvector![-0.15], dvector![0.15])),
        ..MpcSettings::default()
    };
    let p = MpcProblem::build(&m, &s).unwrap();
    assert_eq!(p.layout.previous_input(), 2..3);
    assert_eq!(p.p(), 4);
    // theta(x, r) refuses a problem that needs the previous input.
    assert!(p.theta(&[0.0, 0.0], &[1.0]).is_err());
    let mut law = MpcLaw::clarabel(&p, QpSettings::default()).unwrap();
    let (a, b) = (&m.a, &m.b);
    let mut x = dvector![0.0, 0.0];
    let (mut u, mut last) = ([0.0], 0.0);
    for _ in 0..150 {
        law.control(x.as_slice(), &[1.0], &mut u).unwrap();
        assert!((u[0] - last).abs() <= 0.15 + 1e-9, "move {}", u[0] - last);
        assert!(u[0].abs() <= 1.0 + 1e-9);
        last = u[0];
        x = a * &x + b * u[0];
    }
    assert!((x[0] - 1.0).abs() < 1e-3, "position {}", x[0]);
    assert_eq!(law.previous_input(), &u);
}

#[test]
fn terminal_set_holds_at_the_end_of_the_horizon() {
    let m = double_integrator();
    // |x_N| <= 0.05 component-wise, from 0.5 away, in 20 steps.
    let ts = TerminalSet {
        a: dmatrix![1.0, 0.0; -1.0, 0.0; 0.0, 1.0; 0.0, -1.0],
        b: DVector::from_element(4, 0.05),
    };
    let p = MpcProblem::build(
        &m,
        &MpcSettings {
            horizon: 20,
            terminal: Terminal::None,
            q1: Weight::Scalar(0.0),
            q2: Weight::Scalar(1.0),
            input_bounds: unit_input(),
            terminal_set: Some(ts.clone()),
            ..MpcSettings::default()
        },
    )
    .unwrap();
    let th = p.theta(&[0.5, 0.0], &[0.0]).unwrap();
    let sol = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default())
        .unwrap()
        .solve(&th)
        .unwrap();
    // Roll the model forward with the solution.
    let mut x = dvector![0.5, 0.0];
    for j in 0..20 {
        x = &m.a * &x + &m.b * sol.z[j];
    }
    // Without a state cost the input energy is least with x_N on the set's
    // boundary: the position bound is active.
    assert!((&ts.a * &x - &ts.b).max() < 1e-9, "x_N = {x}");
    assert!((x[0] - 0.05).abs() < 1e-9, "x_N = {x}");
    let rows: Vec<_> = p
        .rows
        .iter()
        .filter(|l| l.kind == ConstraintKind::TerminalSet)
        .collect();
    assert_eq!(rows.len(), 4);
}

#[test]
fn preview_input_target_and_parameters_sit_where_the_layout_says() {
    let m = double_integrator();
    let p = MpcProblem::build(
        &m,
        &MpcSettings {
            horizon: 6,
            preview: 3,
            du_weight: Some(Weight::Scalar(1.0)),
            input_target: InputTarget::Parameter,
            input_bounds: Some(
                Bounds::new(dvector![-1.0], dvector![1.0]).shifted(dmatrix![0.5, 0.0]),
            ),
            parameters: vec![
                Parameter::new("a", 0.0, 1.0),
                Parameter::new("b", -1.0, 1.0),
            ],
            ..MpcSettings::default()
        },
    )
    .unwrap();
    let l = p.layout;
    assert_eq!(
        (l.state(), l.previous_input(), l.references()),
        (0..2, 2..3, 3..6)
    );
    assert_eq!((l.input_target(), l.parameters()), (6..7, 7..9));
    assert_eq!(l.n_law_reference(), 6);
    // The parameter box: the previous input and the target range over the
    // input bounds at their widest (the window moves by 0.5 a).
    assert_eq!((p.theta_lb[2], p.theta_ub[2]), (-1.0, 1.5));
    assert_eq!((p.theta_lb[7], p.theta_ub[7]), (0.0, 1.0));
    assert_eq!((p.theta_lb[8], p.theta_ub[8]), (-1.0, 1.0));
    // The upper input rows move with parameter a, not b.
    assert_eq!(p.e[(0, 7)], 0.5);
    assert_eq!(p.e[(0, 8)], 0.0);
    assert_eq!(p.row_label(0), "input 0 upper bound at step 0");
    assert_eq!(p.row_label(6), "input 0 lower bound at step 0");
}

#[test]
fn bad_settings_name_the_setting() {
    let m = double_integrator();
    let err = |s: MpcSettings| MpcProblem::build(&m, &s).unwrap_err().to_string();
    let e = err(MpcSettings {
        du_bounds: Some(Bounds::new(dvector![0.1], dvector![0.5])),
        ..MpcSettings::default()
    });
    assert!(e.contains("du_bounds") && e.contains("zero move"), "{e}");
    let e = err(MpcSettings {
        output_bounds: Some(
            Bounds::new(dvector![0.0], dvector![1.0]).with_soft(SoftPenalty {
                quadratic: -1.0,
                linear: 1.0,
            }),
        ),
        ..MpcSettings::default()
    });
    assert!(e.contains("output_bounds soft penalty quadratic"), "{e}");
    let e = err(MpcSettings {
        horizon: 4,
        preview: 5,
        ..MpcSettings::default()
    });
    assert!(e.contains("preview") && e.contains("N = 4"), "{e}");
    let e = err(MpcSettings {
        output_bounds: Some(Bounds::new(dvector![0.0, 0.0], dvector![1.0, 1.0])),
        ..MpcSettings::default()
    });
    assert!(
        e.contains("output_bounds lower") && e.contains("1 entries"),
        "{e}"
    );
    let e = err(MpcSettings {
        input_bounds: Some(
            Bounds::new(dvector![-1.0], dvector![1.0]).shifted(DMatrix::from_element(1, 1, 1.0)),
        ),
        ..MpcSettings::default()
    });
    assert!(e.contains("input_bounds lower_shift"), "{e}");
    let e = err(MpcSettings {
        input_target: InputTarget::Fixed(dvector![0.0, 1.0]),
        ..MpcSettings::default()
    });
    assert!(e.contains("input_target"), "{e}");
    let e = err(MpcSettings {
        terminal_set: Some(TerminalSet {
            a: DMatrix::zeros(1, 3),
            b: dvector![1.0],
        }),
        ..MpcSettings::default()
    });
    assert!(e.contains("terminal_set"), "{e}");
    let e = err(MpcSettings {
        parameters: vec![Parameter::new("p", 1.0, 0.0)],
        ..MpcSettings::default()
    });
    assert!(e.contains("parameter 0 (p)"), "{e}");
}
