//! What [`identify`](crate::workflow::identify()) does: the library form of
//! `kestrel identify`'s flags.

use super::prefilter::Prefilter;
use super::segment::Segment;
use crate::n4sid::{MatrixEstimate, Weighting};
use crate::pem::Criterion;
#[cfg(doc)]
use crate::pem::PemSettings;
#[cfg(doc)]
use crate::validate::ValidationReport;
use nalgebra::DMatrix;
use std::ops::RangeInclusive;

/// Identification method of the workflow.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// Subspace identification only.
    N4sid,
    /// Prediction-error method started from N4SID.
    #[default]
    Pem,
}

/// The lags of the ARX that [`Start::Arx`] reduces when
/// [`IdentifySpec::horizon`] is not given.
pub const ARX_LAGS: usize = 10;

/// The subspace method that gives the model (or the PEM start).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Start {
    /// N4SID ([`IdentifySpec::weighting`], [`IdentifySpec::n4sid_matrices`],
    /// block rows [`IdentifySpec::horizon`]): biased on closed-loop data.
    #[default]
    N4sid,
    /// PBSID-opt ([`pbsid`](crate::pbsid)), consistent on closed-loop
    /// data: a VARX with [`IdentifySpec::horizon`] past lags (default
    /// [`PbsidSettings::past`](crate::PbsidSettings::past)'s: 20, fewer on
    /// a short record) then the state from its predictor Markov
    /// parameters.
    Pbsid,
    /// A high-order ARX with [`IdentifySpec::horizon`] lags (default 10)
    /// reduced by balanced truncation, `K` refitted
    /// ([`arx_reduction`](crate::arx_reduction())): consistent on
    /// closed-loop data.
    Arx,
    /// An ARMAX with [`IdentifySpec::horizon`] lags (default 10) in `A`,
    /// `B` and `C` reduced the same way
    /// ([`ArxReductionSettings::noise_lags`](crate::ArxReductionSettings::noise_lags)):
    /// few lags describe coloured noise, e.g. the model's own order as
    /// `ny x lags`, where the ARX needs many.
    Armax,
}

/// What the PEM step fits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PemFocus {
    /// One-step prediction errors over `A, B, C, (D), K` (MATLAB's default).
    #[default]
    Prediction,
    /// Simulation errors with `K = 0` (output-error model).
    Simulation,
    /// Simulation errors for `A, B, C, (D)`, then the noise model `K` by
    /// one-step prediction with the dynamics fixed: the simulation fit of
    /// an output-error model and the k-step predictions of a Kalman
    /// predictor on top of it. Suits near-integrating plants flown in
    /// closed loop, where the one-step optimum drifts in simulation.
    SimulationThenNoise,
    /// Multi-step prediction errors (the `1..=horizon`-step-ahead
    /// predictions together, [`PemSettings::horizon`]) over
    /// `A, B, C, (D), K`, then the noise model `K` alone with the dynamics
    /// fixed by the `1..=pem_horizon`-step criterion
    /// ([`IdentifySpec::pem_horizon`]; 1: one-step). The simulation fit is
    /// that of the multi-step dynamics (it does not depend on `K`); the
    /// second stage tunes the short-range predictions. On the DaISy steam
    /// generator it comes closest to the open-source subspace targets
    /// with one model, without meeting all three (see `docs/sysid.md` in the
    /// repository).
    MultiStepThenNoise {
        /// Prediction horizon `h >= 1` of the dynamics stage.
        horizon: usize,
    },
}

impl PemFocus {
    /// Whether a noise-model stage (`K` with the dynamics fixed) follows
    /// the first PEM stage.
    pub fn refits_noise(&self) -> bool {
        matches!(
            self,
            PemFocus::SimulationThenNoise | PemFocus::MultiStepThenNoise { .. }
        )
    }
}

/// What PEM re-estimates on the estimation data after `balred` (with
/// [`Method::Pem`]).
///
/// Balanced truncation (or DC matching) of the innovation model reduces
/// `[B K]` together, so the reduced `K` is no longer the optimal
/// predictor gain of the reduced dynamics and the residual tests of the
/// reduced model would judge a gain nobody estimated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AfterReduction {
    /// Keep the reduced model as `balred` returns it.
    Keep,
    /// Re-estimate the noise model `K` (and the initial states) by
    /// one-step prediction with the reduced `A, B, C, D` fixed
    /// ([`PemSettings::fixed_dynamics`]): the simulation fit is unchanged.
    #[default]
    NoiseModel,
    /// Refine the whole reduced model with the spec's [`PemFocus`]
    /// (estimating `D` when the reduced model has a feed-through, as
    /// matched DC gives); with [`PemFocus::Simulation`] `K` stays zero.
    All,
}

/// A linear map of the inputs before identification, `u_new = M u`
/// (e.g. a mixer's virtual inputs from the actuator commands).
#[derive(Clone, Debug, PartialEq)]
pub struct InputMap {
    /// `nu_new x nu` matrix.
    pub matrix: DMatrix<f64>,
    /// Names of the new inputs (`nu_new`).
    pub names: Vec<String>,
}

/// Zero-phase Butterworth low-pass applied to inputs and outputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lowpass {
    /// Filter order.
    pub order: usize,
    /// Cut-off in rad/s.
    pub cutoff: f64,
}

/// What to identify and how: the library form of `kestrel identify`'s flags.
#[derive(Clone, Debug, PartialEq)]
pub struct IdentifySpec {
    /// Estimation segments (time units of the data); empty: all data.
    pub estimate: Vec<Segment>,
    /// Validation segments; empty: validate on the estimation data.
    pub validate: Vec<Segment>,
    /// Model order; `None`: suggested from the singular values.
    pub order: Option<usize>,
    /// Reduce to this order by balanced truncation.
    pub reduce: Option<usize>,
    /// Keep the DC gain when reducing.
    pub match_dc: bool,
    /// What PEM re-estimates after the reduction.
    pub after_reduction: AfterReduction,
    /// N4SID only, or PEM started from N4SID.
    pub method: Method,
    /// The subspace method (the model for [`Method::N4sid`], the start
    /// of PEM otherwise).
    pub start: Start,
    /// N4SID weighting.
    pub weighting: Weighting,
    /// N4SID horizon (block rows); `None`: chosen from the order.
    pub horizon: Option<usize>,
    /// How N4SID estimates the system matrices (output-error least
    /// squares, the default, or the state-sequence regression).
    pub n4sid_matrices: MatrixEstimate,
    /// PEM focus.
    pub focus: PemFocus,
    /// Prediction horizon of every one-step (prediction-focus) PEM stage:
    /// `h > 1` fits the `1..=h`-step-ahead predictions together
    /// ([`PemSettings::horizon`]); 1 is the one-step criterion.
    pub pem_horizon: usize,
    /// The prediction steps (each in `1..=pem_horizon`) whose errors enter
    /// the criterion of the prediction-focus PEM stages whose horizon is
    /// [`IdentifySpec::pem_horizon`] ([`PemSettings::steps`]); empty: all of
    /// `1..=pem_horizon`. For example `pem_horizon: 5, pem_steps: vec![1,
    /// 5]` with [`Criterion::Fit`] fits the sum of the one-step and
    /// five-step fits. Not used by the dynamics stage of
    /// [`PemFocus::MultiStepThenNoise`].
    pub pem_steps: Vec<usize>,
    /// How the PEM stages weigh the errors of the outputs (and steps):
    /// [`Criterion::Trace`] (default), [`Criterion::Determinant`] or
    /// [`Criterion::Fit`] (the sum of the RMS errors, the mean fit).
    pub criterion: Criterion,
    /// Estimate a feed-through `D`.
    pub feedthrough: bool,
    /// Largest number of PEM iterations.
    pub max_iterations: usize,
    /// Map the inputs before identification (applied before the offsets).
    pub input_map: Option<InputMap>,
    /// Known input operating point in the units of the data *before* the
    /// input map (mapped with it); `None`: mean of the estimation data.
    pub u0: Option<Vec<f64>>,
    /// Known output offset (e.g. gyro bias); `None`: mean of the estimation data.
    pub y0: Option<Vec<f64>>,
    /// Optional zero-phase low-pass of inputs and outputs.
    pub lowpass: Option<Lowpass>,
    /// The vibration pre-filter chosen from the periodogram (only
    /// without [`IdentifySpec::lowpass`]).
    pub prefilter: Prefilter,
    /// Horizons of the k-step prediction table.
    pub horizons: Vec<usize>,
    /// The automatic structure choice: the dimensions it may choose by
    /// blocked cross-validation inside the estimation data (a dimension
    /// the spec fixes, e.g. `order: Some(n)`, stays fixed); `None`: fit
    /// the spec as given (the behaviour before the choice existed).
    pub auto: Option<AutoSelect>,
    /// Lag counts of the best-ARX baseline rows of the validation table
    /// (`best ARX k-step (n lags)`, [`ValidationReport::add_arx_baseline`]);
    /// `None`: no ARX rows.
    pub arx_baseline: Option<RangeInclusive<usize>>,
}

/// What the automatic structure choice of
/// [`identify`](crate::workflow::identify()) may choose, and its limits.
/// The choice looks at the estimation data only (never at the validation
/// segments).
#[derive(Clone, Debug, PartialEq)]
pub struct AutoSelect {
    /// Choose the order in `1..=max_order` (only when
    /// [`IdentifySpec::order`] is `None`; with [`IdentifySpec::reduce`] `r`,
    /// in `r..=max_order`: every candidate is reduced to `r` states and
    /// compared so).
    pub order: bool,
    /// Largest order tried (at least 1, and at least the reduced order).
    pub max_order: usize,
    /// Choose the start: N4SID with `B, D` by output-error least squares
    /// or `A, B, C, D` by the state regression, or PBSID. The feed-through
    /// ([`IdentifySpec::feedthrough`]) is tried only by the open-loop
    /// candidates ([`AutoSelect::open_loop`]): on closed-loop data `D`
    /// learns the controller's reaction within the sample.
    pub start: bool,
    /// Choose the PEM focus and its prediction horizon (one-step PEM,
    /// multi-step `1..=h` PEM, or multi-step then `K`, with `h` the
    /// largest table horizon); only with [`Method::Pem`].
    pub focus: bool,
    /// Number of consecutive blocks (folds), at least 2.
    pub folds: usize,
    /// Largest number of samples of all blocks together: a longer
    /// record's blocks keep their first samples (a 500 Hz log is scored
    /// on parts of its blocks; the final fit uses all the data).
    pub max_fold_samples: usize,
    /// Largest number of iterations of each PEM stage on a fold (the
    /// final fit uses [`IdentifySpec::max_iterations`]).
    pub fold_iterations: usize,
    /// The work of all fold fits together, in units of one PEM
    /// iteration's estimated work `N p n^2 h` (samples, free parameters,
    /// states squared, prediction steps): candidates are planned in their
    /// order and one whose fold fits would exceed what is left is skipped
    /// (and reported). The candidates and their iteration caps depend on
    /// the data's size only, never on the machine's speed or load.
    pub work_budget: f64,
    /// The work of one fold fit (same unit): a fit's PEM iterations are
    /// capped at `fold_work / (work of one iteration)`, between
    /// [`AutoSelect::min_iterations`] and [`AutoSelect::fold_iterations`].
    pub fold_work: f64,
    /// The work of the final fit on all estimation data (same unit): its
    /// iterations are capped at `final_work / (work of one iteration)`,
    /// at least [`AutoSelect::min_iterations`] and at most
    /// [`IdentifySpec::max_iterations`].
    pub final_work: f64,
    /// Fewest PEM iterations a work cap leaves a fit.
    pub min_iterations: usize,
    /// Safety stop in seconds: no new fold fit starts after it (the
    /// candidates whose folds all finished are compared, and the report
    /// says that the stop fired). With the default work budget it fires
    /// only on a machine several times slower (or busier) than 2 cores.
    pub time_budget: f64,
    /// Try the prediction focus with `A`'s modes allowed up to this
    /// radius ([`PemSettings::max_radius_a`]; the predictor stays
    /// stable, the simulation diverges) at the best order and start;
    /// `None`: not tried.
    pub radius_a: Option<f64>,
    /// When the [`feedback_test`](crate::feedback_test) finds no feedback
    /// in the estimation data (open loop), also try at the chosen order,
    /// with the start and the focus free: N4SID state regression with a
    /// feed-through `D` (block rows [`AutoSelect::open_loop_horizons`]),
    /// then PEM with `D` and `K` estimated, [`Criterion::Fit`] over the
    /// prediction steps `{1, h}` (`h` the largest table horizon), run to
    /// [`AutoSelect::open_loop_iterations`] or convergence. With feedback
    /// (or when the test cannot run) nothing is added.
    pub open_loop: bool,
    /// N4SID block rows of the open-loop candidates (`None`: chosen from
    /// the order, as [`IdentifySpec::horizon`]); one candidate each, a
    /// count too short for the order left out. Default `[None, Some(5)]`:
    /// the default and the short start that the steam generator's own
    /// cross-validation chose (`steam_regression`).
    pub open_loop_horizons: Vec<Option<usize>>,
    /// PEM iterations of the open-loop candidates (folds and final fit;
    /// they stop earlier on the tolerances): their work is planned at
    /// this count against [`AutoSelect::work_budget`] (default 60; on the
    /// steam generator at order 9 each candidate's folds plan 1.2e10 of
    /// the default budget of 5e10).
    pub open_loop_iterations: usize,
    /// Worker threads.
    pub threads: usize,
}

impl Default for AutoSelect {
    fn default() -> Self {
        AutoSelect {
            order: true,
            max_order: 8,
            start: true,
            focus: true,
            folds: 3,
            fold_iterations: 10,
            max_fold_samples: 6000,
            work_budget: 5.0e10,
            fold_work: 8e8,
            final_work: 2e9,
            min_iterations: 3,
            time_budget: 60.0,
            radius_a: Some(1.02),
            open_loop: true,
            open_loop_horizons: vec![None, Some(5)],
            open_loop_iterations: 60,
            threads: std::thread::available_parallelism().map_or(2, |n| n.get().min(4)),
        }
    }
}

impl Default for IdentifySpec {
    fn default() -> Self {
        IdentifySpec {
            estimate: Vec::new(),
            validate: Vec::new(),
            order: None,
            reduce: None,
            match_dc: false,
            after_reduction: AfterReduction::NoiseModel,
            method: Method::Pem,
            start: Start::N4sid,
            weighting: Weighting::Moesp,
            horizon: None,
            n4sid_matrices: MatrixEstimate::OutputError,
            focus: PemFocus::Prediction,
            pem_horizon: 1,
            pem_steps: Vec::new(),
            criterion: Criterion::Trace,
            feedthrough: false,
            max_iterations: 30,
            input_map: None,
            u0: None,
            y0: None,
            lowpass: None,
            prefilter: Prefilter::None,
            horizons: vec![1, 5],
            auto: Some(AutoSelect::default()),
            arx_baseline: Some(2..=10),
        }
    }
}
