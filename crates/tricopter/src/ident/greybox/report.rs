//! The result of the estimation: parameter table, stages, validation.

use core::fmt;
use kestrel_sysid::{InnovationModel, IoData, Result, StopReason, ValidationReport, validate};
use kestrel_tricopter_model::GreyBoxParams;
use nalgebra::DVector;

/// One row of the parameter table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParameterEstimate {
    /// The name ([`GreyBoxParams::NAMES`]).
    pub name: &'static str,
    /// Whether it was estimated.
    pub free: bool,
    /// The initial value given.
    pub initial: f64,
    /// The value the search started from (differs when the initial guess
    /// could not hover, see the module docs).
    pub start: f64,
    /// The estimate.
    pub estimate: f64,
    /// Standard error from the Gauss-Newton Hessian (`None` when fixed or
    /// when the Hessian is singular).
    pub std_error: Option<f64>,
}

/// A stage of the search.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The equation-error start: one-step errors with the measured states
    /// reset to the measurement (`K = A C'`), physical parameters free.
    EquationError,
    /// Simulation errors (`K = 0`), physical parameters free.
    Simulation,
    /// One-step errors, physical parameters and `K` free.
    Prediction,
    /// One-step errors, `K` free, physical parameters fixed.
    Noise,
}

/// What one search stage did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageSummary {
    /// Which stage.
    pub stage: Stage,
    /// Iterations (Jacobian evaluations).
    pub iterations: usize,
    /// Cost `J` of the stage's criterion at its start.
    pub initial_cost: f64,
    /// The same at its end.
    pub cost: f64,
    /// Why it stopped.
    pub stop: StopReason,
}

/// Result of [`estimate_grey_box`](crate::ident::greybox::estimate_grey_box).
#[derive(Clone, Debug)]
pub struct GreyBoxReport {
    /// The estimated parameters.
    pub estimate: GreyBoxParams,
    /// The initial guess as given.
    pub initial: GreyBoxParams,
    /// Where the search started.
    pub start: GreyBoxParams,
    /// Whether the start differs from the initial guess (no hover trim).
    pub start_adjusted: bool,
    /// Whether `k_t` and `k_tau` come from [`GreyBoxSpec::operating_point`](crate::ident::greybox::GreyBoxSpec::operating_point).
    pub from_operating_point: bool,
    /// The parameter table, in [`GreyBoxParams::NAMES`] order.
    pub parameters: Vec<ParameterEstimate>,
    /// The identified discrete model (`K = 0` for the simulation focus).
    pub model: InnovationModel,
    /// The estimated initial state of every experiment.
    pub x0: Vec<DVector<f64>>,
    /// Cost `J` (see the module docs) at the start of the first stage.
    pub initial_cost: f64,
    /// Cost of the last stage at the end.
    pub cost: f64,
    /// Every search stage in order (equation-error start, the physical
    /// parameters, the noise model).
    pub stages: Vec<StageSummary>,
    /// Iterations (Jacobian evaluations) of the physical-parameter stage
    /// of the focus.
    pub iterations: usize,
    /// Why the physical-parameter stage stopped.
    pub stop: StopReason,
    /// Fit table (simulation, k-step, persistence, residual tests) of
    /// [`GreyBoxReport::model`] on the estimation data.
    pub fit: ValidationReport,
}

impl GreyBoxReport {
    /// The fit table of the estimated model on other data (e.g. a
    /// validation set with the same offsets removed).
    pub fn validate(&self, data: &IoData, horizons: &[usize]) -> Result<ValidationReport> {
        validate(&self.model, data, horizons)
    }
}

impl fmt::Display for GreyBoxReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.start_adjusted {
            writeln!(
                f,
                "initial guess cannot hover: k_tau reduced to {:.4e} for the start",
                self.start.k_tau
            )?;
        }
        if self.from_operating_point {
            writeln!(
                f,
                "k_t, k_tau from the operating point (hover trim), held fixed"
            )?;
        }
        for s in &self.stages {
            writeln!(
                f,
                "grey-box PEM stage {:?}: {} iterations, cost {:.6e} -> {:.6e}, stopped: {:?}",
                s.stage, s.iterations, s.initial_cost, s.cost, s.stop
            )?;
        }
        writeln!(
            f,
            "{:<11}{:>13}{:>13}{:>13}{:>13}",
            "parameter", "initial", "start", "estimate", "std error"
        )?;
        for p in &self.parameters {
            let se = match (p.free, p.std_error) {
                (false, _) => "fixed".to_string(),
                (true, Some(s)) => format!("{s:.4e}"),
                (true, None) => "-".to_string(),
            };
            writeln!(
                f,
                "{:<11}{:>13.5e}{:>13.5e}{:>13.5e}{:>13}",
                p.name, p.initial, p.start, p.estimate, se
            )?;
        }
        write!(f, "{}", self.fit)
    }
}
