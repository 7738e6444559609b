//! One call per closed-loop run: [`fly_mpc`], [`fly_offset_free`],
//! [`fly_pi`], each returning a [`RunResult`].

use crate::closed_loop::run::{run_mpc, run_pid};
use crate::closed_loop::settings::RunSettings;
use crate::closed_loop::trace::{StepMetrics, Trace};
use crate::constants::pwm;
use crate::error::TricopterError;
use kestrel_core::formats::SsModel;
use kestrel_kalman::KalmanDesign;
use kestrel_mpc::{MpcLaw, MpcProblem, OffsetFreeDesign, ParametricQpSolver};
use kestrel_tricopter_model::RatePid;

/// A closed-loop run: the trace and the step-response figures of the
/// scenario's first step.
#[derive(Clone, Debug, PartialEq)]
pub struct RunResult {
    /// One row per sample, with the pulses and the cost `J`.
    pub trace: Trace,
    /// Rise time, overshoot, RMS error, effort, bound violation.
    pub metrics: StepMetrics,
}

/// Largest model order the closed-loop helpers support (the estimator is
/// kestrel-kalman's const-dimension stationary filter).
pub const MAX_STATES: usize = 16;

macro_rules! with_filter {
    ($design:expr, |$f:ident| $body:expr) => {{
        let design = $design;
        let kf_err = |e: kestrel_kalman::KalmanError| {
            TricopterError::setting("Kalman filter", e.to_string())
        };
        match design.nx() {
            1 => {
                let mut $f = design.filter::<f64, 1, 4, 3>().map_err(kf_err)?;
                $body
            }
            2 => {
                let mut $f = design.filter::<f64, 2, 4, 3>().map_err(kf_err)?;
                $body
            }
            3 => {
                let mut $f = design.filter::<f64, 3, 4, 3>().map_err(kf_err)?;
                $body
            }
            4 => {
                let mut $f = design.filter::<f64, 4, 4, 3>().map_err(kf_err)?;
                $body
            }
            5 => {
                let mut $f = design.filter::<f64, 5, 4, 3>().map_err(kf_err)?;
                $body
            }
            6 => {
                let mut $f = design.filter::<f64, 6, 4, 3>().map_err(kf_err)?;
                $body
            }
            7 => {
                let mut $f = design.filter::<f64, 7, 4, 3>().map_err(kf_err)?;
                $body
            }
            8 => {
                let mut $f = design.filter::<f64, 8, 4, 3>().map_err(kf_err)?;
                $body
            }
            9 => {
                let mut $f = design.filter::<f64, 9, 4, 3>().map_err(kf_err)?;
                $body
            }
            10 => {
                let mut $f = design.filter::<f64, 10, 4, 3>().map_err(kf_err)?;
                $body
            }
            11 => {
                let mut $f = design.filter::<f64, 11, 4, 3>().map_err(kf_err)?;
                $body
            }
            12 => {
                let mut $f = design.filter::<f64, 12, 4, 3>().map_err(kf_err)?;
                $body
            }
            13 => {
                let mut $f = design.filter::<f64, 13, 4, 3>().map_err(kf_err)?;
                $body
            }
            14 => {
                let mut $f = design.filter::<f64, 14, 4, 3>().map_err(kf_err)?;
                $body
            }
            15 => {
                let mut $f = design.filter::<f64, 15, 4, 3>().map_err(kf_err)?;
                $body
            }
            16 => {
                let mut $f = design.filter::<f64, 16, 4, 3>().map_err(kf_err)?;
                $body
            }
            n => {
                return Err(TricopterError::dim(
                    "closed-loop design model",
                    format!("1 to {MAX_STATES} states"),
                    format!("{n} states"),
                ));
            }
        }
    }};
}

fn fly_with<S: ParametricQpSolver>(
    model: &SsModel,
    problem: &MpcProblem,
    law: &mut MpcLaw<S>,
    kalman: &KalmanDesign,
    settings: &RunSettings,
) -> Result<RunResult, TricopterError> {
    if model.nu() != 4 || model.ny() != 3 {
        return Err(TricopterError::dim(
            "closed-loop design model",
            "4 pulse inputs and 3 rate outputs",
            format!("{} inputs and {} outputs", model.nu(), model.ny()),
        ));
    }
    if (kalman.nx(), kalman.nu(), kalman.ny()) != (model.nx(), 4, 3) {
        return Err(TricopterError::dim(
            "closed-loop Kalman filter",
            format!(
                "{} states, 4 inputs and 3 outputs (the model's)",
                model.nx()
            ),
            format!(
                "{} states, {} inputs and {} outputs",
                kalman.nx(),
                kalman.nu(),
                kalman.ny()
            ),
        ));
    }
    let mut plant = settings.plant(model)?;
    let sc = &settings.scenario;
    let trace = with_filter!(kalman, |f| run_mpc(
        &mut plant,
        law,
        &mut f,
        model,
        problem,
        sc,
        |l| Some(l.last_z().to_vec())
    )?);
    let (t, from, to) = sc.first_step();
    let metrics = trace.step_metrics(t, from, to);
    Ok(RunResult { trace, metrics })
}

/// Flies an MPC law in the closed loop of section 7.7: the plant of
/// `settings`, the stationary Kalman filter of `kalman` (designed for
/// `model`, e.g. the thesis's [`kalman_design`](crate::closed_loop::kalman_design)), the law (any [`ParametricQpSolver`]: clarabel,
/// explicit, fast gradient) on `theta = [x_hat; r - y0; throttle]`, the
/// actuation with clipping; the trace holds the cost `J` of the law's
/// whole move sequence at every step.
///
/// ```
/// use kestrel_mpc::{MpcLaw, QpSettings};
/// use kestrel_tricopter::closed_loop::{RunSettings, fly_mpc, kalman_design};
/// use kestrel_tricopter::{ProblemSize, default_weights, identified_model, tricopter_problem};
/// let model = identified_model().unwrap();
/// let (q1, q2) = default_weights();
/// let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
/// let mut law = MpcLaw::clarabel(&problem, QpSettings::default()).unwrap();
/// let kalman = kalman_design(&model).unwrap();
/// let run = fly_mpc(&model, &problem, &mut law, &kalman, &RunSettings::default()).unwrap();
/// assert_eq!(run.metrics.max_bound_violation, 0.0);          // inputs inside their ranges
/// let last = run.trace.rows.last().unwrap();                // on the step [1, -1, 0.5] at the end
/// assert!((0..3).all(|k| (last.rates[k] - last.reference[k]).abs() < 0.15));
/// ```
pub fn fly_mpc<S: ParametricQpSolver>(
    model: &SsModel,
    problem: &MpcProblem,
    law: &mut MpcLaw<S>,
    kalman: &KalmanDesign,
    settings: &RunSettings,
) -> Result<RunResult, TricopterError> {
    fly_with(model, problem, law, kalman, settings)
}

/// [`fly_mpc`] for an offset-free design: `kalman` is a filter of the
/// augmented model (e.g. [`kalman_design_with_disturbance`](crate::closed_loop::kalman_design_with_disturbance) with
/// `design.nd`).
pub fn fly_offset_free<S: ParametricQpSolver>(
    design: &OffsetFreeDesign,
    law: &mut MpcLaw<S>,
    kalman: &KalmanDesign,
    settings: &RunSettings,
) -> Result<RunResult, TricopterError> {
    fly_with(&design.augmented, &design.problem, law, kalman, settings)
}

/// Flies the baseline PI rate controller (kestrel-tricopter-model's
/// `RatePid` with its default gains, mixing around `model`'s trim) on the
/// raw gyro samples.
pub fn fly_pi(model: &SsModel, settings: &RunSettings) -> Result<RunResult, TricopterError> {
    let trim = crate::problems::tricopter_trim(model)?;
    let o = trim.offsets;
    let mut pid = RatePid::new(
        kestrel_tricopter_model::RatePidGains::default(),
        kestrel_tricopter_model::Mixer::new([o[0], o[1], o[2], pwm::SERVO_CENTER + o[3]]),
    );
    let mut plant = settings.plant(model)?;
    let sc = &settings.scenario;
    let trace = run_pid(&mut plant, &mut pid, &trim, sc, model.ts)?;
    let (t, from, to) = sc.first_step();
    let metrics = trace.step_metrics(t, from, to);
    Ok(RunResult { trace, metrics })
}
