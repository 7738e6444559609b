//! The three MPC laws on the thesis problem (identified model, thesis
//! horizon and weights) along the closed loop of section 7.7.1: the
//! explicit law (kestrel-empc) flies the polished reference QP law
//! (kestrel-mpc) to rounding, and the fast gradient law (kestrel-fgm)
//! approaches it as its iteration count grows, from every start.

use kestrel_core::formats::SsModel;
use kestrel_empc::ExplicitSolver;
use kestrel_fgm::{FastGradientSolver, FgmOptions, FgmStart};
use kestrel_kalman::KalmanDesign;
use kestrel_mpc::{MpcLaw, MpcProblem, ParametricQpSolver, QpSettings};
use kestrel_tricopter::closed_loop::{RunResult, RunSettings, fly_mpc, kalman_design};
use kestrel_tricopter::{ProblemSize, default_weights, identified_model, tricopter_problem};

fn thesis() -> (SsModel, MpcProblem, KalmanDesign) {
    let model = identified_model().unwrap();
    let (q1, q2) = default_weights();
    let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
    let kalman = kalman_design(&model).unwrap();
    (model, problem, kalman)
}

/// The closed loop with the polished reference QP (default settings).
fn qp_run(settings: &RunSettings) -> RunResult {
    let (model, problem, kalman) = thesis();
    let mut law = MpcLaw::clarabel(&problem, QpSettings::default()).unwrap();
    fly_mpc(&model, &problem, &mut law, &kalman, settings).unwrap()
}

/// Largest pulse difference between two runs (us).
fn max_pwm_diff(a: &RunResult, b: &RunResult) -> f64 {
    assert_eq!(a.trace.rows.len(), b.trace.rows.len());
    a.trace
        .rows
        .iter()
        .zip(&b.trace.rows)
        .flat_map(|(r, s)| (0..4).map(move |i| (r.pwm[i] - s.pwm[i]).abs()))
        .fold(0.0, f64::max)
}

/// Largest relative cost difference between two runs.
fn max_cost_diff(a: &RunResult, b: &RunResult) -> f64 {
    a.trace
        .rows
        .iter()
        .zip(&b.trace.rows)
        .map(|(r, s)| (r.cost - s.cost).abs() / r.cost.abs().max(1.0))
        .fold(0.0, f64::max)
}

#[test]
fn explicit_law_flies_the_qp_law() {
    let (model, problem, kalman) = thesis();
    let mut law = ExplicitSolver::mpc_law(&problem, &kestrel_empc::Settings::default()).unwrap();
    for settings in [RunSettings::default(), RunSettings::noisy()] {
        let qp = qp_run(&settings);
        let ex = fly_mpc(&model, &problem, &mut law, &kalman, &settings).unwrap();
        let (d, dj) = (max_pwm_diff(&qp, &ex), max_cost_diff(&qp, &ex));
        eprintln!(
            "explicit vs QP: {} regions, {} of {} steps outside the explored set, max |pwm diff| {d:.2e} us, max rel |J diff| {dj:.2e}",
            law.solver().regions(),
            law.solver().outside(),
            ex.trace.rows.len()
        );
        assert!(law.solver().regions() > 1);
        assert_eq!(law.solver().outside(), 0);
        // The same law: the same pulses and costs to rounding (the
        // reference is polished to the exact active-set solution).
        assert!(d < 1e-9, "{d} us");
        assert!(dj < 1e-9, "{dj}");
    }
    // Wrong lengths and NaN parameters give errors, not panics.
    let ex = law.solver_mut();
    let mut z = vec![0.0; problem.n()];
    let mut theta = vec![0.0; problem.p()];
    theta[0] = f64::NAN;
    assert!(ex.solve_into(&theta, &mut z).is_err());
    assert!(ex.solve_into(&[0.0; 3], &mut z).is_err());
}

#[test]
fn fast_gradient_approaches_the_qp_law_with_more_iterations() {
    let (model, problem, kalman) = thesis();
    let settings = RunSettings::default();
    let qp = qp_run(&settings);
    let mut last = [f64::INFINITY; 3];
    for iterations in [2, 12, 50, 400] {
        let mut diffs = [0.0; 3];
        for (k, start) in [FgmStart::Cold, FgmStart::Warm, FgmStart::WarmShifted]
            .into_iter()
            .enumerate()
        {
            let opts = FgmOptions {
                iterations,
                start,
                ..FgmOptions::default()
            };
            let mut law = FastGradientSolver::mpc_law(&problem, &opts).unwrap();
            let run = fly_mpc(&model, &problem, &mut law, &kalman, &settings).unwrap();
            // Always inside the bounds, whatever the iteration count.
            assert!(run.metrics.max_bound_violation <= 0.0, "{:?}", run.metrics);
            diffs[k] = max_pwm_diff(&qp, &run);
        }
        eprintln!("FGM {iterations} iterations: max |pwm - pwm_QP| cold/warm/shifted {diffs:?} us");
        for k in 0..3 {
            assert!(
                diffs[k] <= last[k],
                "{iterations} iterations, start {k}: {} > {}",
                diffs[k],
                last[k]
            );
        }
        last = diffs;
    }
    // 400 iterations reach the polished reference to rounding.
    assert!(last.iter().all(|d| *d < 1e-9), "{last:?}");
}
