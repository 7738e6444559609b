//! Stage 9: closed-loop runs on the nonlinear tricopter (section 7.7): the
//! MPC of the thesis-sized problem with each solver, and the baseline PI.
//! Every MPC run flies the Kalman filter of stage 4.

use super::config::Config;
use super::error::{Context, Result};
use super::explicit::Explicit;
use super::fast_gradient::FastGradient;
use super::kalman::KalmanStage;
use super::problems::Problems;
use crate::closed_loop::{
    PlantKind, ReferenceStep, RunSettings, Scenario, StepMetrics, Trace, fly_mpc, fly_pi,
};
use kestrel_empc::ExplicitSolver;
use kestrel_fgm::{FastGradientSolver, FgmOptions, FgmStart};
use kestrel_mpc::{MpcLaw, QpSettings, ReferenceSolver};
use kestrel_tricopter_model::{GustConfig, GyroConfig, PlantConfig};
use nalgebra::DMatrix;

/// The scenario of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunKind {
    /// No gyro noise or gusts (7.7.1).
    Step,
    /// Gyro noise, bias and gusts (figures 7.18-7.21).
    Noisy,
}

impl RunKind {
    /// `step` or `noisy` (file names).
    pub fn as_str(self) -> &'static str {
        match self {
            RunKind::Step => "step",
            RunKind::Noisy => "noisy",
        }
    }
}

/// The controller of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Controller {
    /// The baseline ACRO rate PI.
    Pi,
    /// The MPC with the reference QP.
    Qp,
    /// The MPC with the explicit law.
    Explicit,
    /// The MPC with the fast gradient method, `k` iterations, cold start.
    Fgm(usize),
}

impl Controller {
    /// `PI`, `QP`, `explicit`, `FGM-k`.
    pub fn name(self) -> String {
        match self {
            Controller::Pi => "PI".into(),
            Controller::Qp => "QP".into(),
            Controller::Explicit => "explicit".into(),
            Controller::Fgm(k) => format!("FGM-{k}"),
        }
    }
}

/// One closed-loop run.
#[derive(Clone, Debug)]
pub struct Run {
    /// The scenario.
    pub kind: RunKind,
    /// The controller.
    pub controller: Controller,
    /// One row per sample.
    pub trace: Trace,
    /// Rise time, overshoot, RMS error, effort, bound violation.
    pub metrics: StepMetrics,
    /// Range of the motor pulses (us).
    pub pwm_range: (f64, f64),
    /// Range of the servo pulse (us).
    pub servo_range: (f64, f64),
    /// The measurement-update gain `M` of the filter design the run flew
    /// (`None` for the PI, which flies the raw gyro).
    pub estimator_gain: Option<DMatrix<f64>>,
}

/// Stage 9's result.
#[derive(Clone, Debug)]
pub struct ClosedLoop {
    /// The scenario (the step run's; the noisy run flies the same).
    pub scenario: Scenario,
    /// Noise seed.
    pub seed: u64,
    /// Every run, the step scenario first.
    pub runs: Vec<Run>,
    /// Largest bound violation of any run (us).
    pub worst_violation: f64,
}

impl ClosedLoop {
    /// The run of a scenario and controller.
    pub fn run(&self, kind: RunKind, c: Controller) -> Option<&Run> {
        self.runs
            .iter()
            .find(|r| r.kind == kind && r.controller == c)
    }
}

/// Stage 9.
///
/// # Errors
/// The plant's, the filter's and the solvers' errors.
pub fn run(
    cfg: &Config,
    pr: &Problems,
    kf: &KalmanStage,
    ex: &Explicit,
    fg: &FastGradient,
    progress: &mut dyn FnMut(&str),
) -> Result<ClosedLoop> {
    let cl = &cfg.closed_loop;
    let problem = &pr.thesis.problem;
    let mpqp = &pr.thesis.mpqp;
    let d = &fg.thesis.design;
    let estimator = &kf.design.kalman;
    let scenario = Scenario {
        duration: cl.duration,
        initial_rates: cl.initial_rates,
        initial_reference: [0.0; 3],
        steps: vec![ReferenceStep {
            time: cl.step_time,
            rates: cl.step,
        }],
        throttle: None,
    };
    let quiet = PlantConfig {
        gyro: GyroConfig::ideal(),
        gust: GustConfig::calm(),
        ..PlantConfig::default()
    };
    let mut runs = Vec::new();
    let mut worst_violation = 0.0f64;
    for (kind, config) in [
        (RunKind::Step, quiet),
        (RunKind::Noisy, PlantConfig::default()),
    ] {
        let settings = RunSettings {
            scenario: scenario.clone(),
            plant: PlantKind::Nonlinear,
            config,
            seed: cl.seed,
        };
        let model = &pr.estimator_model;
        let mut ctrls = vec![Controller::Pi, Controller::Qp, Controller::Explicit];
        ctrls.extend(cl.fgm_iterations.iter().map(|k| Controller::Fgm(*k)));
        for c in ctrls {
            progress(&format!("9. closed loop: {} {}", kind.as_str(), c.name()));
            let (res, gain) = match c {
                Controller::Pi => (
                    fly_pi(&pr.model, &settings).ctx(|| "the PI closed loop".into())?,
                    None,
                ),
                Controller::Qp => {
                    let s = ReferenceSolver::new(mpqp, QpSettings::default())
                        .ctx(|| "the reference QP".into())?;
                    let mut law = MpcLaw::new(problem, s).ctx(|| "the QP law".into())?;
                    (
                        fly_mpc(model, problem, &mut law, estimator, &settings)
                            .ctx(|| "the MPC closed loop".into())?,
                        Some(estimator.filter.m.clone()),
                    )
                }
                Controller::Explicit => {
                    let s = ExplicitSolver::new(ex.thesis.full.tables.clone());
                    let mut law = MpcLaw::new(problem, s).ctx(|| "the explicit law".into())?;
                    (
                        fly_mpc(model, problem, &mut law, estimator, &settings)
                            .ctx(|| "the MPC closed loop".into())?,
                        Some(estimator.filter.m.clone()),
                    )
                }
                Controller::Fgm(k) => {
                    let s = FastGradientSolver::from_design(
                        d,
                        &FgmOptions {
                            iterations: k,
                            start: FgmStart::Cold,
                            settings: d.settings,
                        },
                    )
                    .ctx(|| "the fast gradient solver".into())?;
                    let mut law = MpcLaw::new(problem, s).ctx(|| "the fast gradient law".into())?;
                    (
                        fly_mpc(model, problem, &mut law, estimator, &settings)
                            .ctx(|| "the MPC closed loop".into())?,
                        Some(estimator.filter.m.clone()),
                    )
                }
            };
            let (trace, metrics) = (res.trace, res.metrics);
            let (mut lo, mut hi, mut slo, mut shi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for row in &trace.rows {
                for v in &row.pwm[..3] {
                    lo = lo.min(*v);
                    hi = hi.max(*v);
                }
                slo = slo.min(row.pwm[3]);
                shi = shi.max(row.pwm[3]);
            }
            worst_violation = worst_violation.max(metrics.max_bound_violation);
            runs.push(Run {
                kind,
                controller: c,
                trace,
                metrics,
                pwm_range: (lo, hi),
                servo_range: (slo, shi),
                estimator_gain: gain,
            });
        }
    }
    Ok(ClosedLoop {
        scenario,
        seed: cl.seed,
        runs,
        worst_violation,
    })
}
