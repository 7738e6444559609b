//! Tests of N4SID: noise-free recovery, the noise model, bad data.

use super::{MatrixEstimate, N4sidSettings, Weighting, n4sid, n4sid_of_order};
use crate::data::IoData;
use crate::error::SysidError;
use crate::model::InnovationModel;
use crate::synthetic;
use nalgebra::DMatrix;

fn max_tf_error(a: &InnovationModel, b: &InnovationModel) -> f64 {
    (0..40)
        .map(|i| {
            let w = std::f64::consts::PI * i as f64 / 40.0;
            let ga = a.frequency_response(w).unwrap();
            let gb = b.frequency_response(w).unwrap();
            (ga - &gb).norm() / gb.norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn noise_free_data_recover_the_system_for_every_weighting_estimate_and_past() {
    let truth = synthetic::random_model(4, 2, 2, 11, 0.85);
    let mut det = truth.clone();
    det.k.fill(0.0);
    let data = synthetic::simulate(&det, 600, 0.0, 2).unwrap();
    for w in [Weighting::Moesp, Weighting::Cva, Weighting::Unweighted] {
        for (matrices, past) in [
            (MatrixEstimate::OutputError, None),
            (MatrixEstimate::StateRegression, None),
            (MatrixEstimate::StateRegression, Some(15)),
            (MatrixEstimate::OutputError, Some(15)),
        ] {
            let r = n4sid(
                &data,
                &N4sidSettings {
                    weighting: w,
                    max_order: 8,
                    past_horizon: past,
                    matrices,
                    ..Default::default()
                },
            )
            .unwrap();
            assert_eq!(
                r.suggested_order, 4,
                "{w:?} {matrices:?} {past:?}: {:?}",
                r.singular_values
            );
            let err = max_tf_error(&r.model, &det);
            assert!(err < 1e-6, "{w:?} {matrices:?} {past:?}: {err}");
        }
    }
}

/// One-step prediction error variance of `m` on `data`, from the
/// predictor's least-squares initial state.
fn one_step_mse(m: &InnovationModel, data: &IoData) -> f64 {
    let e = &data.experiments()[0];
    let x0 = crate::validate::estimate_x0_predictor(m, &e.u, &e.y).unwrap();
    let r = m.predict_one_step(&e.u, &e.y, &x0).unwrap().residuals;
    r.norm_squared() / r.len() as f64
}

#[test]
fn state_regression_estimates_the_noise_model() {
    // Coloured noise (a large K): the state-sequence regression gives
    // both the dynamics and a one-step predictor close to the true
    // Kalman predictor's on fresh data.
    let mut truth = synthetic::random_model(3, 2, 2, 5, 0.9);
    truth.k *= 3.0;
    assert!(truth.radius_predictor() < 1.0);
    let data = synthetic::simulate(&truth, 5000, 0.3, 9).unwrap();
    let fresh = synthetic::simulate(&truth, 5000, 0.3, 10).unwrap();
    let best = one_step_mse(&truth, &fresh);
    for past in [None, Some(20)] {
        let r = n4sid(
            &data,
            &N4sidSettings {
                order: Some(3),
                past_horizon: past,
                matrices: MatrixEstimate::StateRegression,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(max_tf_error(&r.model, &truth) < 0.1, "{past:?}");
        assert!(r.model.radius_predictor() < 1.0);
        let mse = one_step_mse(&r.model, &fresh);
        assert!(mse < 1.03 * best, "{past:?}: {mse} vs {best}");
    }
}

#[test]
fn noisy_data_give_a_close_model_with_a_stable_predictor() {
    let truth = synthetic::random_model(3, 2, 2, 5, 0.9);
    let data = synthetic::simulate(&truth, 5000, 0.2, 9).unwrap();
    let r = n4sid_of_order(&data, 3);
    assert!(max_tf_error(&r.model, &truth) < 0.1);
    assert!(r.model.radius_predictor() < 1.0);
}

#[test]
fn bad_data_are_errors() {
    let truth = synthetic::random_model(3, 2, 2, 5, 0.9);
    let data = synthetic::simulate(&truth, 30, 0.1, 1).unwrap();
    let e = n4sid(
        &data,
        &N4sidSettings {
            order: Some(3),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(matches!(e, SysidError::TooFewSamples { .. }), "{e}");
    let u = DMatrix::from_fn(
        500,
        2,
        |k, j| if j == 0 { ((k * 7) % 13) as f64 } else { 1.0 },
    );
    let y = DMatrix::from_fn(500, 1, |k, _| ((k * 5) % 11) as f64);
    let d = IoData::new(1.0, u, y).unwrap();
    let e = n4sid(&d, &N4sidSettings::default()).unwrap_err();
    assert!(matches!(e, SysidError::ConstantInput { .. }), "{e}");
    assert!(
        n4sid(
            &data,
            &N4sidSettings {
                order: Some(0),
                ..Default::default()
            }
        )
        .is_err()
    );
    let past0 = N4sidSettings {
        order: Some(3),
        past_horizon: Some(0),
        ..Default::default()
    };
    assert!(matches!(
        n4sid(&data, &past0),
        Err(SysidError::InvalidArgument(_))
    ));
    let long_past = N4sidSettings {
        order: Some(2),
        max_order: 2,
        horizon: Some(3),
        past_horizon: Some(20),
        ..Default::default()
    };
    let e = n4sid(&data, &long_past).unwrap_err();
    assert!(matches!(e, SysidError::TooFewSamples { .. }), "{e}");
    assert!(
        n4sid(
            &data,
            &N4sidSettings {
                horizon: Some(1),
                ..Default::default()
            }
        )
        .is_err()
    );
}

#[test]
fn default_horizon_shrinks_to_a_short_record() {
    // 80 samples, 2 inputs, 2 outputs: the usual horizon 10 needs 20 x 4
    // Hankel rows and has 61 columns; the largest that fits is 8 (64
    // rows, 65 columns), and 9 (72 rows, 63 columns) does not.
    let truth = synthetic::random_model(2, 2, 2, 3, 0.8);
    let data = synthetic::simulate(&truth, 80, 0.01, 2).unwrap();
    let order2 = N4sidSettings {
        order: Some(2),
        ..Default::default()
    };
    let r = n4sid(&data, &order2).unwrap();
    assert_eq!(r.horizon, 8);
    let at = |i: usize| {
        n4sid(
            &data,
            &N4sidSettings {
                horizon: Some(i),
                ..order2.clone()
            },
        )
    };
    assert!(matches!(at(9), Err(SysidError::TooFewSamples { .. })));
    assert_eq!(at(8).unwrap().model, r.model);
}
