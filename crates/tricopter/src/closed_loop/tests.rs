//! The closed loop against the PI on the thesis's step.

use super::*;
use crate::{ProblemSize, default_weights, identified_model, tricopter_problem};
use kestrel_mpc::{DisturbanceModel, MpcLaw, MpcProblem, QpSettings};

fn qp_settings() -> QpSettings {
    QpSettings {
        kkt_tolerance: Some(1e-7),
        ..QpSettings::default()
    }
}

fn settings(noisy: bool) -> RunSettings {
    let mut s = if noisy {
        RunSettings::noisy()
    } else {
        RunSettings::default()
    };
    s.seed = 5;
    s
}

fn run(size: ProblemSize, noisy: bool) -> RunResult {
    let model = identified_model().unwrap();
    let (q1, q2) = default_weights();
    let problem = tricopter_problem(&model, size, q1, q2).unwrap();
    let mut law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
    let kalman = kalman_design(&model).unwrap();
    fly_mpc(&model, &problem, &mut law, &kalman, &settings(noisy)).unwrap()
}

#[test]
fn both_sizes_track_the_thesis_step_with_the_identified_model() {
    for size in [ProblemSize::Thesis, ProblemSize::Larger] {
        for noisy in [false, true] {
            let RunResult { trace, metrics: m } = run(size, noisy);
            eprintln!("{size:?} noisy={noisy}: {m:?}");
            // Inputs inside their ranges without clipping (to solver accuracy).
            assert!(m.max_bound_violation <= 0.0, "{m:?}");
            assert!(trace.rows.iter().all(|r| !r.saturated));
            assert!(
                trace
                    .rows
                    .iter()
                    .all(|r| r.cost.is_finite() && r.cost >= -1e-9)
            );
            // Settled from [2, 2, 2] before the step and near the new reference at the end.
            let before = trace
                .rows
                .iter()
                .find(|r| (r.t - 1.98).abs() < 1e-6)
                .unwrap();
            let last = trace.rows.last().unwrap();
            for k in 0..3 {
                assert!(
                    before.rates[k].abs() < 0.1,
                    "{size:?} axis {k} before step: {:?}",
                    before.rates
                );
                assert!(
                    (last.rates[k] - last.reference[k]).abs() < 0.15,
                    "{size:?} axis {k} at the end: {:?} vs {:?}",
                    last.rates,
                    last.reference
                );
                assert!(m.rise_time[k].is_finite() && m.rise_time[k] < 0.3, "{m:?}");
            }
            // The filter follows the true rates (it is what the law sees).
            let est_err = trace
                .rows
                .iter()
                .skip(5)
                .flat_map(|r| (0..3).map(move |k| (r.estimated[k] - r.rates[k]).abs()))
                .fold(0.0, f64::max);
            assert!(
                est_err < 0.1,
                "{size:?} noisy={noisy}: estimate off by {est_err}"
            );
        }
    }
}

#[test]
fn mpc_against_the_pi_baseline() {
    // The same step on the same plant: the PI on the raw gyro, the MPC
    // (both sizes) on the Kalman estimate of the identified model.
    let model = identified_model().unwrap();
    for noisy in [false, true] {
        let pi = fly_pi(&model, &settings(noisy)).unwrap().metrics;
        eprintln!("PI noisy={noisy}: {pi:?}");
        assert!(pi.max_bound_violation <= 0.0);
        for size in [ProblemSize::Thesis, ProblemSize::Larger] {
            let m = run(size, noisy).metrics;
            eprintln!("{size:?} noisy={noisy}: {m:?}");
            for k in 0..3 {
                // The MPC rises faster than the PI on every axis ...
                assert!(
                    m.rise_time[k] < pi.rise_time[k],
                    "axis {k}: {m:?} vs {pi:?}"
                );
            }
            // ... and its total RMS tracking error over the step window is
            // at most that of the PI.
            let total = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!(
                total(&m.rms_error) <= total(&pi.rms_error),
                "{m:?} vs {pi:?}"
            );
        }
    }
}

/// Mean absolute tracking error over the last second.
fn steady_error(trace: &Trace) -> f64 {
    let end = trace.rows.last().map_or(0.0, |r| r.t);
    let tail: Vec<&TraceRow> = trace.rows.iter().filter(|r| r.t > end - 1.0).collect();
    tail.iter()
        .map(|r| {
            (0..3)
                .map(|k| (r.reference[k] - r.rates[k]).abs())
                .sum::<f64>()
                / 3.0
        })
        .sum::<f64>()
        / tail.len() as f64
}

#[test]
fn offset_free_option_reduces_steady_error_on_the_nonlinear_plant() {
    let model = identified_model().unwrap();
    let (q1, q2) = default_weights();
    let trim = crate::tricopter_trim(&model).unwrap();
    let design = MpcProblem::build_offset_free(
        &model,
        &trim.constrain(ProblemSize::Thesis.settings(q1.clone(), q2.clone())),
        &DisturbanceModel::OutputStates,
    )
    .unwrap();
    let mut law = MpcLaw::clarabel(&design.problem, qp_settings()).unwrap();
    // Hold the step for 4 s so the disturbance estimate settles.
    let mut s = settings(false);
    s.scenario.duration = 6.0;
    let kalman_of = kalman_design_with_disturbance(&design.augmented, design.nd).unwrap();
    let of = fly_offset_free(&design, &mut law, &kalman_of, &s).unwrap();
    let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
    let mut plain_law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
    let kalman = kalman_design(&model).unwrap();
    let plain = fly_mpc(&model, &problem, &mut plain_law, &kalman, &s).unwrap();
    let (e_of, e_plain) = (steady_error(&of.trace), steady_error(&plain.trace));
    eprintln!(
        "steady error: offset-free {e_of:.4}, plain {e_plain:.4} rad/s; {:?}",
        of.metrics
    );
    assert!(of.metrics.max_bound_violation <= 0.0);
    assert!(
        e_of < 0.5 * e_plain,
        "offset-free {e_of} vs plain {e_plain}"
    );
}

#[test]
fn linear_plant_and_bad_models_through_the_run_helpers() {
    let model = identified_model().unwrap();
    let (q1, q2) = default_weights();
    let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
    let mut law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
    // On its own design model (no mismatch) the MPC settles on the reference.
    let s = RunSettings {
        plant: PlantKind::Linear,
        ..RunSettings::default()
    };
    let kalman = kalman_design(&model).unwrap();
    let run = fly_mpc(&model, &problem, &mut law, &kalman, &s).unwrap();
    assert!(
        steady_error(&run.trace) < 0.05,
        "{}",
        steady_error(&run.trace)
    );
    // A model with the wrong number of outputs is refused, not flown.
    let mut two = model.clone();
    two.c = two.c.rows(0, 2).into_owned();
    two.d = two.d.rows(0, 2).into_owned();
    two.y0 = None;
    two.outputs = None;
    let e = fly_mpc(&two, &problem, &mut law, &kalman, &s).unwrap_err();
    assert!(e.to_string().contains("3 rate outputs"), "{e}");
}

#[test]
fn the_thesis_filter_is_for_the_three_gyro_outputs() {
    let model = identified_model().unwrap();
    // The measurement noise is the thesis's gyro (7.5)-(7.6), the process
    // noise enters through [B, C'] with the thesis's levels.
    let noise = thesis_noise(&model, 0).unwrap();
    for i in 0..3 {
        for j in 0..3 {
            assert_eq!(noise.r[(i, j)], crate::constants::GYRO_COVARIANCE[i][j]);
        }
    }
    let bias = noise.bias.as_ref().unwrap();
    assert_eq!(bias.as_slice(), &crate::constants::GYRO_BIAS);
    assert_eq!(noise.q[(0, 0)], crate::constants::INPUT_NOISE_US.powi(2));
    assert_eq!(noise.q[(4, 4)], crate::constants::GUST_NOISE.powi(2));
    // A model without the gyro's three outputs has no thesis filter.
    let mut two = model.clone();
    two.c = two.c.rows(0, 2).into_owned();
    two.d = two.d.rows(0, 2).into_owned();
    two.y0 = None;
    two.outputs = None;
    let e = kalman_design(&two).unwrap_err();
    assert!(e.to_string().contains("3 outputs"), "{e}");
}

#[test]
fn the_loop_refuses_a_filter_of_another_model() {
    let model = identified_model().unwrap();
    let (q1, q2) = default_weights();
    let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
    let mut law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
    // The physical model's filter has 8 states, the identified model 5.
    let other = kalman_design(&crate::design_model().unwrap()).unwrap();
    let e = fly_mpc(&model, &problem, &mut law, &other, &RunSettings::default()).unwrap_err();
    assert!(e.to_string().contains("closed-loop Kalman filter"), "{e}");
}
