//! Tests of [`FirmwareDesign::from_parts`]'s checks that the design files
//! belong together.

use crate::firmware::{
    DesignError, DesignPart, DesignSettings, FirmwareDesign, ProblemCheck, ProblemFile,
};
use crate::{IDENTIFIED_MODEL_JSON, ProblemSize, default_weights, tricopter_trim};
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_mpc::{DisturbanceModel, MpcProblem};

fn model() -> SsModel {
    SsModel::from_json_str(IDENTIFIED_MODEL_JSON).unwrap()
}

/// The offset-free thesis-sized problem on `model` and its estimator's filter.
fn offset_free(model: &SsModel) -> (kestrel_kalman::KalmanDesign, ProblemFile) {
    let (q1, q2) = default_weights();
    let d = MpcProblem::build_offset_free(
        model,
        &tricopter_trim(model)
            .unwrap()
            .constrain(ProblemSize::Thesis.settings(q1, q2)),
        &DisturbanceModel::OutputStates,
    )
    .unwrap();
    let kalman = crate::closed_loop::kalman_design_with_disturbance(&d.augmented, d.nd).unwrap();
    let problem = ProblemFile {
        problem: d.problem.to_mpqp(),
        model_fingerprint: Some(MpqpProblem::model_fingerprint(&d.augmented)),
    };
    (kalman, problem)
}

fn mismatch(e: DesignError) -> (DesignPart, DesignPart, String) {
    match e {
        DesignError::Mismatch {
            first,
            second,
            detail,
        } => (first, second, detail),
        other => panic!("not a mismatch: {other}"),
    }
}

#[test]
fn the_offset_free_estimator_and_its_problem_belong_to_the_model() {
    let m = model();
    let (kalman, problem) = offset_free(&m);
    let settings = DesignSettings::default();
    let (design, checked) =
        FirmwareDesign::from_parts(&m, Some(kalman.clone()), Some(problem.clone()), &settings)
            .unwrap();
    assert_eq!(design.nx(), m.nx() + 3);
    assert_eq!(checked.disturbance_states, 3);
    assert_eq!(checked.problem, ProblemCheck::Fingerprint);
    // Without a fingerprint only the sizes are checked.
    let old = ProblemFile {
        model_fingerprint: None,
        ..problem.clone()
    };
    let (_, checked) =
        FirmwareDesign::from_parts(&m, Some(kalman.clone()), Some(old), &settings).unwrap();
    assert_eq!(checked.problem, ProblemCheck::SizesOnly);
    // Another plant under the same disturbance states.
    let mut other = m.clone();
    other.b[(2, 1)] *= 1.5;
    let e = FirmwareDesign::from_parts(
        &other,
        Some(kalman.clone()),
        Some(problem.clone()),
        &settings,
    )
    .unwrap_err();
    let (first, second, detail) = mismatch(e);
    assert_eq!((first, second), (DesignPart::Kalman, DesignPart::Model));
    assert!(
        detail.contains("plant part") && detail.contains("B[2][1]"),
        "{detail}"
    );
    // Disturbance states that are not constant.
    let mut drifting = kalman.clone();
    drifting.a[(m.nx(), m.nx())] = 0.99;
    let e = FirmwareDesign::from_parts(&m, Some(drifting), Some(problem.clone()), &settings)
        .unwrap_err();
    assert!(mismatch(e).2.contains("constant disturbance"));
    // A problem built on the plant alone has the wrong parameters; one with
    // another model's fingerprint is refused.
    let (_, foreign) = offset_free(&other);
    let e =
        FirmwareDesign::from_parts(&m, Some(kalman.clone()), Some(foreign), &settings).unwrap_err();
    let (first, second, detail) = mismatch(e);
    assert_eq!((first, second), (DesignPart::Problem, DesignPart::Kalman));
    assert!(detail.contains("model_fingerprint"), "{detail}");
    // The filter alone: the problem built here would not have its states.
    let e = FirmwareDesign::from_parts(&m, Some(kalman), None, &settings).unwrap_err();
    assert_eq!(mismatch(e).0, DesignPart::Problem);
}

#[test]
fn new_refuses_a_filter_of_another_model_of_the_same_size() {
    let m = model();
    let mut other = m.clone();
    other.a[(0, 0)] += 0.01;
    let kalman = crate::closed_loop::kalman_design(&other).unwrap();
    let (q1, q2) = default_weights();
    let problem = crate::tricopter_problem(&m, ProblemSize::Thesis, q1, q2)
        .unwrap()
        .to_mpqp();
    let e = FirmwareDesign::new(&m, kalman, problem, &DesignSettings::default()).unwrap_err();
    let (first, second, detail) = mismatch(e);
    assert_eq!((first, second), (DesignPart::Kalman, DesignPart::Model));
    assert!(detail.contains("A[0][0]"), "{detail}");
}

/// A problem built on the model without the throttle parameter (a plain
/// input box, as `kestrel mpc` builds without `--tricopter`) is named as
/// such, not as a problem for one state fewer.
#[test]
fn a_problem_without_the_throttle_is_named() {
    let m = model();
    let kalman = crate::closed_loop::kalman_design(&m).unwrap();
    let (q1, q2) = default_weights();
    let mut problem = crate::tricopter_problem(&m, ProblemSize::Thesis, q1, q2)
        .unwrap()
        .to_mpqp();
    // Drop the throttle, the last parameter.
    let p = problem.p();
    problem.f_theta = problem.f_theta.remove_row(p - 1);
    problem.e = problem.e.remove_column(p - 1);
    problem.theta_lb = problem.theta_lb.remove_row(p - 1);
    problem.theta_ub = problem.theta_ub.remove_row(p - 1);
    problem.validate().unwrap();
    let file = ProblemFile {
        problem,
        model_fingerprint: Some(MpqpProblem::model_fingerprint(&m)),
    };
    let settings = DesignSettings::default();
    let e = FirmwareDesign::from_parts(&m, Some(kalman.clone()), Some(file.clone()), &settings)
        .unwrap_err();
    let (first, second, detail) = mismatch(e);
    assert_eq!((first, second), (DesignPart::Problem, DesignPart::Kalman));
    assert!(detail.contains("without the throttle"), "{detail}");
    // Without the fingerprint it could as well be a problem for one state
    // fewer: the sizes are all that is said.
    let old = ProblemFile {
        model_fingerprint: None,
        ..file
    };
    let e = FirmwareDesign::from_parts(&m, Some(kalman), Some(old), &settings).unwrap_err();
    let detail = mismatch(e).2;
    assert!(
        !detail.contains("without the throttle") && detail.contains("for 4 states"),
        "{detail}"
    );
}

/// A trim beyond Q15.16 (a model whose inputs are not in microseconds)
/// is refused naming the table entry.
#[test]
fn a_trim_beyond_fixed_point_names_the_mixer_entry() {
    let mut m = model();
    m.u0 = m.u0.map(|u0| u0.add_scalar(40_000.0));
    let e = FirmwareDesign::from_model(&m, &DesignSettings::default())
        .and_then(|d| crate::firmware::generate_tables(&d))
        .unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("MIX_OFFSET[") && text.contains("does not fit Q15.16"),
        "{text}"
    );
}
