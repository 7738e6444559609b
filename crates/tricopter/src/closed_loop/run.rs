//! One run of the loop: an MPC law on the state estimate
//! ([`run_mpc`]) or the baseline PI on the raw gyro ([`run_pid`]).

use crate::closed_loop::plant::RatePlant;
use crate::closed_loop::scenario::Scenario;
use crate::closed_loop::trace::{Trace, TraceRow};
use crate::error::TricopterError;
use crate::problems::TricopterTrim;
use kestrel_core::formats::SsModel;
use kestrel_core::{ControlLaw, StateEstimator};
use kestrel_mpc::MpcProblem;
use kestrel_tricopter_model::RatePid;
use nalgebra::DVector;

/// Runs an MPC loop: gyro -> estimator measurement update -> law (theta =
/// `[x_hat; r; throttle]`) -> actuation (trim + move + throttle, clipped)
/// -> plant -> estimator time update with the applied input.
///
/// The estimator works in the model's input coordinates: its time update
/// gets `u0 + applied move` (with the model's `u0`, so a filter built from
/// the same `kestrel.ss.v1` model removes its operating point itself), its
/// measurement update the raw gyro sample. The law's cost `J` is evaluated
/// from `problem` when the law's whole move sequence is known (`z_of`).
#[allow(clippy::too_many_arguments)]
pub fn run_mpc<P: RatePlant, L: ControlLaw<Scalar = f64>, E: StateEstimator<Scalar = f64>>(
    plant: &mut P,
    law: &mut L,
    estimator: &mut E,
    model: &SsModel,
    problem: &MpcProblem,
    scenario: &Scenario,
    z_of: impl Fn(&L) -> Option<Vec<f64>>,
) -> Result<Trace, TricopterError> {
    if model.ny() != 3 {
        return Err(TricopterError::dim(
            "closed-loop model outputs",
            "3 rate outputs [p, q, r]",
            format!("{} outputs", model.ny()),
        ));
    }
    let trim = crate::problems::tricopter_trim(model)?;
    let u0 = model.u0.clone().unwrap_or_else(|| DVector::zeros(4));
    let y0 = model.y0.clone().unwrap_or_else(|| DVector::zeros(3));
    let throttle = scenario.throttle.unwrap_or(trim.hover_throttle);
    if law.nx() != estimator.nx() || law.nu() != 4 || law.nr() != 4 {
        return Err(TricopterError::dim(
            "control law",
            format!(
                "{} states, 4 references (rates and throttle), 4 inputs",
                estimator.nx()
            ),
            format!(
                "{} states, {} references, {} inputs",
                law.nx(),
                law.nr(),
                law.nu()
            ),
        ));
    }
    let pinv = model
        .c
        .clone()
        .pseudo_inverse(1e-12)
        .map_err(|e| TricopterError::setting("C", e.to_string()))?;
    let ts = model.ts;
    let steps = (scenario.duration / ts).round() as usize;
    let mut trace = Trace {
        rows: Vec::with_capacity(steps),
        trim_pwm: trim.actuate(&[0.0; 4], throttle)?.pwm,
    };
    // Start the estimator at the state that explains the first sample.
    let y_first = plant.measure();
    let x_first = &pinv * (DVector::from_column_slice(&y_first) - &y0);
    estimator.reset(x_first.as_slice())?;
    let mut u = [0.0; 4];
    for k in 0..steps {
        let t = k as f64 * ts;
        let reference = scenario.reference_at(t);
        let y = if k == 0 { y_first } else { plant.measure() };
        estimator.measurement_update(&y)?;
        let x_hat = estimator.estimate().to_vec();
        // The law works in the model's deviation outputs: `r - y0`.
        let r = [
            reference[0] - y0[0],
            reference[1] - y0[1],
            reference[2] - y0[2],
            throttle,
        ];
        law.control(&x_hat, &r, &mut u)?;
        let act = trim.actuate(&u, throttle)?;
        let cost = match z_of(law) {
            Some(z) => problem.cost(
                &DVector::from_vec(z),
                &problem.theta(&x_hat, &r[..problem.layout.n_law_reference()])?,
            ),
            None => f64::NAN,
        };
        let y_est = &model.c * DVector::from_column_slice(&x_hat) + &y0;
        trace.rows.push(TraceRow {
            t,
            reference,
            throttle,
            rates: plant.rates(),
            measured: y,
            estimated: [y_est[0], y_est[1], y_est[2]],
            pwm: act.pwm,
            saturated: act.saturated.iter().any(|s| *s),
            cost,
        });
        plant.advance(&act.pwm)?;
        let u_model: Vec<f64> = (0..4).map(|i| u0[i] + act.applied[i]).collect();
        estimator.time_update(&u_model)?;
    }
    Ok(trace)
}

/// Runs the baseline PI rate controller on the raw gyro samples.
pub fn run_pid<P: RatePlant>(
    plant: &mut P,
    pid: &mut RatePid<f64>,
    trim: &TricopterTrim,
    scenario: &Scenario,
    ts: f64,
) -> Result<Trace, TricopterError> {
    let throttle = scenario.throttle.unwrap_or(trim.hover_throttle);
    let steps = (scenario.duration / ts).round() as usize;
    let mut trace = Trace {
        rows: Vec::with_capacity(steps),
        trim_pwm: trim.actuate(&[0.0; 4], throttle)?.pwm,
    };
    for k in 0..steps {
        let t = k as f64 * ts;
        let reference = scenario.reference_at(t);
        let y = plant.measure();
        let out = pid.update(&y, &reference, throttle)?;
        trace.rows.push(TraceRow {
            t,
            reference,
            throttle,
            rates: plant.rates(),
            measured: y,
            estimated: y,
            pwm: out.pwm,
            saturated: out.any_saturated(),
            cost: f64::NAN,
        });
        plant.advance(&out.pwm)?;
    }
    Ok(trace)
}
