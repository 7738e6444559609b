//! Grey-box identification of the tricopter's physical parameters: the
//! prediction-error method over the parameters of the linearised rate
//! model of `kestrel-tricopter-model` (inertias, thrust and drag
//! constants, actuator time constants), which the thesis could not do
//! (its grey-box model fitted 0.006 %).
//!
//! # Model
//!
//! For a parameter vector `g` ([`GreyBoxParams`]) the map
//! [`grey_box_model`] re-trims the aircraft at hover, linearises it
//! ([`kestrel_tricopter_model::grey_box_rate_model`], kind
//! [`RateModelKind::Rates`] or [`RateModelKind::WithActuators`], inputs
//! [`RateInputs::Pwm`] or [`RateInputs::Virtual`]) and discretises it with
//! zero-order hold at the data's sample time. The known parameters (mass,
//! arm length, ESC map, servo gain, spins) come from
//! [`GreyBoxSpec::base`]. The data are deviations from the operating point
//! (subtract the trim or the means first, as for [`crate::pem`]).
//!
//! # Criterion and search
//!
//! With outputs scaled by their standard deviations `s_j`, the cost is the
//! mean squared scaled prediction error
//! `J = 1/(N ny) sum_t sum_j (e_j(t) / s_j)^2` of
//!
//! - [`GreyBoxFocus::Simulation`]: the simulation error (`K = 0`,
//!   output-error model);
//! - [`GreyBoxFocus::Prediction`]: the one-step error of the innovation
//!   form `x+ = A x + B u + K e` with the gain `K` (all `nx x ny` entries)
//!   estimated jointly with the physical parameters;
//! - [`GreyBoxFocus::SimulationThenNoise`]: the simulation fit of the
//!   physical parameters, then `K` alone on one-step errors with the
//!   physics fixed (the focus of the black-box models of
//!   [`crate::tricopter::thesis_spec`]).
//!
//! With [`GreyBoxSpec::disturbance`] the model carries `ny` integrating
//! angular-acceleration states on `p, q, r` (unmeasured torques: gusts,
//! trim offsets), driven through `K` in the prediction focus and constant
//! per experiment in the simulation focus.
//!
//! Every focus starts (unless [`GreyBoxSettings::equation_error_start`] is
//! off) with an equation-error stage ([`Stage::EquationError`]): one-step
//! errors of the predictor with `K = A C'`, whose measured states are
//! reset to the measurement every step, so the residuals are nearly
//! linear in the gains and the search converges from starts as far off as
//! Table 7.1 (`k_t` 1000 times too large); the focus's stage follows from
//! its estimate. Every stage is reported ([`GreyBoxReport::stages`]).
//!
//! The free physical parameters are searched in log scale
//! (`theta_i = ln g_i`: positivity for free, inertias of 0.04 and thrust
//! constants of 1.5e-5 equally conditioned), and clamped to
//! [`GreyBoxSpec::lower`]/[`GreyBoxSpec::upper`]; the initial state of
//! every experiment is estimated alongside. The search is Levenberg-
//! Marquardt (Marquardt's diagonal scaling) on the exact Jacobian of the
//! residuals from the forward sensitivity recursion
//!
//! ```text
//! dx(t+1)/dθ = (A - K C) dx(t)/dθ + dA/dθ x(t) + dB/dθ u(t) + dK/dθ e(t),
//! de(t)/dθ   = -C dx(t)/dθ,
//! ```
//!
//! so the cost gradient `2/(N ny) Ψ' r` is analytic. The derivatives
//! `dA/dθ`, `dB/dθ` of the *parametrisation* (trim, linearisation and
//! zero-order hold as one map) are central finite differences in log
//! scale with step [`GreyBoxSettings::derivative_step`] (relative error
//! about `1e-9`; one-sided at the edge of the valid set, e.g. Table 7.1's
//! `I_xx = I_yy + I_zz` on the inertia triangle inequality); the cost
//! gradient itself is never a difference of `J`.
//! A trial point at which the aircraft cannot hover or a parameter is
//! invalid is a rejected step (the damping grows), never an error.
//!
//! Standard errors come from the Gauss-Newton Hessian at the optimum with
//! every output weighed by its residual variance,
//! `cov(θ) = (Ψ' Σ^-1 Ψ)^-1` (the physical block: the Schur complement of
//! the gain and initial states), and the delta method
//! `se(g_i) = g_i se(θ_i)`. A parameter on an active bound is held
//! (projected steps); the search then stops on the projected gradient.
//! They assume white residuals; simulation errors of the integrating rate
//! dynamics are not white, so read them as a lower bound there.
//!
//! # The thesis's initial guess
//!
//! [`GreyBoxParams::thesis_initial_guess`] (Table 7.1) cannot hover with
//! the known aircraft: `k_tau / k_t = 0.5 m`, and no tilt of the rear rotor
//! cancels that reaction torque. When the initial guess has no trim and
//! `k_tau` is free, the search starts from it with `k_tau` halved until
//! the aircraft trims ([`GreyBoxReport::start`], `start_adjusted`);
//! otherwise it is an error.
//!
//! # Identifiability
//!
//! Given the known mass, arm length, ESC and servo maps, the rate data
//! determine well: the roll and pitch gains `sqrt(k_t) / I_xx`,
//! `sqrt(k_t) / I_yy` (the thrust derivative at hover is
//! `2 k_t w0 = 2 sqrt(k_t T0)` with `T0 ~ m g / 3`), `I_zz` (the servo
//! column is `T0 l / I_zz`, independent of `k_t`) and the actuator
//! constants `motor_tau`, `servo_wn`, `servo_zeta`. `k_t` and `k_tau`
//! separately are *weakly* identifiable: the yaw row's motor columns only
//! see `k_tau / sqrt(k_t)` and the throttle-to-yaw path is barely excited
//! in flight, and `k_t` alone enters only through the hover tilt
//! (`sin alpha0 ~ 3 k_tau / (k_t l)`). On the simulator's flights all
//! eight come out within 5 %, but `k_t`'s standard error is about 6 %.
//! The fix: the operating point. The hover pulses fix `k_t` (throttle:
//! rotor speed, `3 k_t w0^2 = m g`) and `k_tau / k_t` (servo: tilt), which
//! [`thrust_and_drag_from_trim`] inverts; with
//! [`GreyBoxSpec::operating_point`] set (the means removed from the data)
//! they are held at those values and the search estimates the other six.
//! The kind [`RateModelKind::Rates`] has no actuator dynamics, so
//! `motor_tau`, `servo_wn`, `servo_zeta` do not enter it: leave them fixed
//! there (a free parameter the model does not depend on is an error).
//!
//! # Results on the simulator
//!
//! `cargo run --release -p kestrel-sysid --example greybox` (flights no. 2
//! and 3, 250 s, seed 1, the thesis's estimation and validation
//! intervals, started from Table 7.1, [`GreyBoxSpec::closed_loop_flights`]
//! with the operating point): every parameter within 4.2 % of the
//! simulator's (`I_zz` -3.6 %, the largest systematic error with a 0.25 %
//! standard error), about 5 s. On the validation set the grey-box model's
//! 1-step and 5-step fits (99.1 %, 96.4 % mean) are above the black-box
//! 8 -> 5 model's (95.8 %, 86.0 %); its simulation fit (45 %) is below
//! (66 %): the physical model integrates the unmeasured gust torque, as
//! the true linearised model does (see the crate README); it is within
//! 1.4 points of the simulator's own linearised model (46.4 %).
//!
//! The remaining 3-4 % errors are deterministic, not noise: they are the
//! same on noiseless, gust-free flights (`I_xx` -3.9 %, `I_yy` -4.0 %,
//! `I_zz` -3.4 %). The excited flights are not at hover: the aircraft
//! leans on average, so the mean throttle is 7 us above the hover trim
//! (rotor speed +1.4 %) and the mean thrust above `m g / 3`. The model is
//! linearised at hover, so its thrust gains are a little low, and the
//! inertias come out a little small to compensate; `k_t` from the mean
//! throttle is -2.8 % (`(1/1.014)^2`).
//!
//! ```
//! use kestrel_sysid::greybox::{estimate_grey_box, grey_box_model, GreyBoxSpec};
//! use kestrel_sysid::IoData;
//! use kestrel_tricopter_model::{GreyBoxParams, Params};
//! use nalgebra::{DMatrix, DVector};
//! // Noiseless data from the grey-box model of the default aircraft.
//! let spec = GreyBoxSpec::default();
//! let truth = GreyBoxParams::from_params(&Params::default());
//! let model = grey_box_model(&truth, &spec, 0.02).unwrap();
//! let u = DMatrix::from_fn(400, 4, |t, j| 20.0 * (((t / (7 + 5 * j)) % 2) as f64 - 0.5));
//! let y = model.simulate(&u, &DVector::zeros(model.nx())).unwrap();
//! let data = IoData::new(0.02, u, y).unwrap();
//! // Start 20 % off and recover the truth.
//! let start = GreyBoxParams::from_array(&truth.to_array().map(|v| 1.2 * v));
//! let report = estimate_grey_box(&data, &spec, &start).unwrap();
//! for (e, t) in report.estimate.to_array().iter().zip(truth.to_array()) {
//!     assert!((e / t - 1.0).abs() < 1e-4);
//! }
//! println!("{report}");
//! ```

use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::spectral_radius;
use crate::model::InnovationModel;
use crate::pem::StopReason;
use crate::validate::{ValidationReport, estimate_x0_simulation, validate};
use core::fmt;
use kestrel_core::formats::SsModel;
use kestrel_tricopter_model::{
    GreyBoxParams, ModelError, Params, RateInputs, RateModelKind, grey_box_rate_model,
};
use nalgebra::{DMatrix, DVector};

/// What the grey-box criterion measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GreyBoxFocus {
    /// Simulation errors, `K = 0` (output-error model).
    #[default]
    Simulation,
    /// One-step prediction errors; `K` estimated with the parameters.
    Prediction,
    /// Simulation errors for the physical parameters, then one-step
    /// errors for `K` alone with the physics fixed.
    SimulationThenNoise,
}

/// Settings of the Levenberg-Marquardt search of [`estimate_grey_box`].
#[derive(Clone, Debug, PartialEq)]
pub struct GreyBoxSettings {
    /// Largest number of iterations (per stage).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Stop when `max |dJ/dθ| / J` is below this.
    pub gradient_tolerance: f64,
    /// Stop when the step is shorter than this relative to `1 + |θ|`.
    pub step_tolerance: f64,
    /// Central-difference step of the parametrisation derivative, in log scale.
    pub derivative_step: f64,
    /// Run the equation-error stage first (see [`Stage::EquationError`]):
    /// robust against starts far from the truth, such as Table 7.1.
    pub equation_error_start: bool,
    /// Horizons of the k-step rows of the fit table.
    pub horizons: Vec<usize>,
}

impl Default for GreyBoxSettings {
    fn default() -> Self {
        GreyBoxSettings {
            max_iterations: 60,
            cost_tolerance: 1e-10,
            gradient_tolerance: 1e-10,
            step_tolerance: 1e-10,
            derivative_step: 1e-5,
            equation_error_start: true,
            horizons: vec![1, 5],
        }
    }
}

/// What to estimate and how.
#[derive(Clone, Debug, PartialEq)]
pub struct GreyBoxSpec {
    /// Which parameters are free, in [`GreyBoxParams::NAMES`] order; the
    /// others stay at the initial value.
    pub free: [bool; 8],
    /// The rate model's states.
    pub kind: RateModelKind,
    /// The rate model's inputs (the data must have the same columns).
    pub inputs: RateInputs,
    /// The criterion.
    pub focus: GreyBoxFocus,
    /// Add `ny` integrating disturbance states (angular accelerations on
    /// the measured rates, `d' = 0`, `p' = ... + d_p`): a noise model for
    /// unmeasured torques (gusts, trim offsets) driven through `K`.
    pub disturbance: bool,
    /// The known parameters (mass, arm length, ESC map, servo gain, spins);
    /// its grey-box fields are replaced by the estimate.
    pub base: Params,
    /// Lower bounds (exclusive of zero: every parameter stays positive).
    pub lower: GreyBoxParams,
    /// Upper bounds.
    pub upper: GreyBoxParams,
    /// The measured operating point `[pwm1, pwm2, pwm3, servo]` (us, e.g.
    /// the means removed from the data): when given, `k_t` and `k_tau` are
    /// computed from it by [`thrust_and_drag_from_trim`] and held fixed
    /// (the rate data alone determine them poorly, see the module docs).
    pub operating_point: Option<[f64; 4]>,
    /// Search settings.
    pub settings: GreyBoxSettings,
}

impl Default for GreyBoxSpec {
    /// All eight parameters free, the model with actuators and PWM inputs,
    /// simulation focus, the default aircraft's known parameters, no bounds
    /// but positivity.
    fn default() -> Self {
        GreyBoxSpec {
            free: [true; 8],
            kind: RateModelKind::WithActuators,
            inputs: RateInputs::Pwm,
            focus: GreyBoxFocus::Simulation,
            disturbance: false,
            base: Params::default(),
            lower: GreyBoxParams::from_array(&[0.0; 8]),
            upper: GreyBoxParams::from_array(&[f64::INFINITY; 8]),
            operating_point: None,
            settings: GreyBoxSettings::default(),
        }
    }
}

impl GreyBoxSpec {
    /// The spec for closed-loop flights with gusts (the simulator's
    /// flights no. 2 and 3): [`GreyBoxFocus::Prediction`] with the
    /// integrating disturbance states, all parameters free. The
    /// simulation focus is biased there: the gust torque is unmeasured and
    /// the pilot's inputs react to it, so the output-error model of the
    /// integrating rates trades physics for drift.
    pub fn closed_loop_flights(base: Params) -> Self {
        GreyBoxSpec {
            focus: GreyBoxFocus::Prediction,
            disturbance: true,
            base,
            ..Default::default()
        }
    }

    /// The default spec with only the named parameters free (names of
    /// [`GreyBoxParams::NAMES`]); an unknown name is an error.
    pub fn with_free(names: &[&str]) -> Result<Self> {
        let mut free = [false; 8];
        for n in names {
            let i = GreyBoxParams::index_of(n).ok_or_else(|| {
                SysidError::invalid(format!(
                    "unknown grey-box parameter \"{n}\" (expected one of {:?})",
                    GreyBoxParams::NAMES
                ))
            })?;
            free[i] = true;
        }
        Ok(GreyBoxSpec {
            free,
            ..Default::default()
        })
    }
}

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

/// Result of [`estimate_grey_box`].
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
    /// Whether `k_t` and `k_tau` come from [`GreyBoxSpec::operating_point`].
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

/// The discrete grey-box model of `g` at sample time `ts` (`K = 0`): the
/// map the search fits (trim, linearisation, zero-order hold).
pub fn grey_box_model(g: &GreyBoxParams, spec: &GreyBoxSpec, ts: f64) -> Result<InnovationModel> {
    let mut m =
        grey_box_rate_model(g, &spec.base, spec.kind, spec.inputs).map_err(|e| model_error(&e))?;
    if spec.disturbance {
        // Integrating angular-acceleration disturbances on p, q, r.
        let (n, ny, nu) = (m.a.nrows(), m.c.nrows(), m.b.ncols());
        let mut a = DMatrix::zeros(n + ny, n + ny);
        a.view_mut((0, 0), (n, n)).copy_from(&m.a);
        a.view_mut((0, n), (n, ny)).copy_from(&m.c.transpose());
        let mut b = DMatrix::zeros(n + ny, nu);
        b.view_mut((0, 0), (n, nu)).copy_from(&m.b);
        let mut c = DMatrix::zeros(ny, n + ny);
        c.view_mut((0, 0), (ny, n)).copy_from(&m.c);
        m = SsModel::new(0.0, a, b, c, m.d.clone())
            .map_err(|e| SysidError::invalid(format!("grey-box model: {e}")))?;
    }
    let d = m
        .c2d(ts)
        .map_err(|e| SysidError::invalid(format!("discretising the grey-box model: {e}")))?;
    let ny = d.c.nrows();
    let nx = d.a.nrows();
    InnovationModel::new(ts, d.a, d.b, d.c, d.d, DMatrix::zeros(nx, ny))
}

fn model_error(e: &ModelError) -> SysidError {
    SysidError::invalid(format!("grey-box model: {e}"))
}

/// Data of one experiment as columns of time series (rows = samples).
struct Series {
    u: Vec<DVector<f64>>,
    y: Vec<DVector<f64>>,
}

/// The search problem: which parameters move and how they map to a model.
struct Problem<'a> {
    spec: &'a GreyBoxSpec,
    ts: f64,
    /// Indices (into the 8) of the free physical parameters of this stage.
    phys: Vec<usize>,
    /// Whether the entries of `K` are parameters.
    gain: Gain,
    /// Fixed physical parameters (log values are taken from theta for free ones).
    g_fixed: GreyBoxParams,
    nx: usize,
    ny: usize,
    series: Vec<Series>,
    /// Output scales `s_j`.
    sy: Vec<f64>,
    /// Total residual count `N ny`.
    m_total: usize,
    /// Log bounds of the free physical parameters.
    lo: Vec<f64>,
    hi: Vec<f64>,
}

/// How the innovation gain `K` is chosen in a search stage.
#[derive(Clone, Debug)]
enum Gain {
    /// A fixed gain (zero: simulation).
    Fixed(DMatrix<f64>),
    /// Every entry a parameter.
    Free,
    /// `K = A C'`: the measured states are replaced by the measurement
    /// every step (`A - KC = A (I - C'C)`), the equation-error start.
    Reset,
}

/// Everything one evaluation gives.
struct Eval {
    model: InnovationModel,
    /// Scaled residuals `r = e_j / (s_j sqrt(N ny))`, stacked by experiment, time, output.
    r: DVector<f64>,
    /// `dr/dθ` (when asked for).
    jac: Option<DMatrix<f64>>,
}

impl Problem<'_> {
    fn n_params(&self) -> usize {
        self.phys.len()
            + if self.k_free() { self.nx * self.ny } else { 0 }
            + self.nx * self.series.len()
    }

    fn k_free(&self) -> bool {
        matches!(self.gain, Gain::Free)
    }

    fn off_k(&self) -> usize {
        self.phys.len()
    }

    fn off_x0(&self) -> usize {
        self.off_k() + if self.k_free() { self.nx * self.ny } else { 0 }
    }

    fn params_of(&self, theta: &DVector<f64>) -> GreyBoxParams {
        let mut v = self.g_fixed.to_array();
        for (k, &i) in self.phys.iter().enumerate() {
            v[i] = theta[k].exp();
        }
        GreyBoxParams::from_array(&v)
    }

    fn model_of(&self, theta: &DVector<f64>) -> Result<InnovationModel> {
        let mut m = grey_box_model(&self.params_of(theta), self.spec, self.ts)?;
        m.k = match &self.gain {
            Gain::Free => DMatrix::from_fn(self.nx, self.ny, |i, j| {
                theta[self.off_k() + i * self.ny + j]
            }),
            Gain::Fixed(k) => k.clone(),
            Gain::Reset => &m.a * m.c.transpose(),
        };
        Ok(m)
    }

    fn x0s_of(&self, theta: &DVector<f64>) -> Vec<DVector<f64>> {
        (0..self.series.len())
            .map(|e| self.x0_of(theta, e))
            .collect()
    }

    fn x0_of(&self, theta: &DVector<f64>, e: usize) -> DVector<f64> {
        let o = self.off_x0() + e * self.nx;
        DVector::from_fn(self.nx, |i, _| theta[o + i])
    }

    /// `dA/dθ_k`, `dB/dθ_k` of the free physical parameters by central
    /// differences of the parametrisation in log scale.
    fn model_derivatives(
        &self,
        theta: &DVector<f64>,
        at: &InnovationModel,
    ) -> Result<Vec<(DMatrix<f64>, DMatrix<f64>)>> {
        let h = self.spec.settings.derivative_step;
        let mut out = Vec::with_capacity(self.phys.len());
        for k in 0..self.phys.len() {
            let mut tp = theta.clone();
            let mut tm = theta.clone();
            tp[k] += h;
            tm[k] -= h;
            let mp = grey_box_model(&self.params_of(&tp), self.spec, self.ts);
            let mm = grey_box_model(&self.params_of(&tm), self.spec, self.ts);
            // One-sided at the edge of the valid set (e.g. the inertia
            // triangle inequality of Table 7.1, which holds with equality).
            out.push(match (mp, mm) {
                (Ok(p), Ok(m)) => ((p.a - m.a) / (2.0 * h), (p.b - m.b) / (2.0 * h)),
                (Ok(p), Err(_)) => ((p.a - &at.a) / h, (p.b - &at.b) / h),
                (Err(_), Ok(m)) => ((&at.a - m.a) / h, (&at.b - m.b) / h),
                (Err(e), Err(_)) => return Err(e),
            });
        }
        Ok(out)
    }

    fn evaluate(&self, theta: &DVector<f64>, with_jac: bool) -> Result<Eval> {
        let model = self.model_of(theta)?;
        let np = self.n_params();
        let (nx, ny) = (self.nx, self.ny);
        let abar = &model.a - &model.k * &model.c;
        let derivs = if with_jac {
            self.model_derivatives(theta, &model)?
        } else {
            Vec::new()
        };
        let norm = (self.m_total as f64).sqrt();
        let mut r = DVector::zeros(self.m_total);
        let mut jac = with_jac.then(|| DMatrix::zeros(self.m_total, np));
        let mut row = 0;
        for (ei, s) in self.series.iter().enumerate() {
            let mut x = self.x0_of(theta, ei);
            // Sensitivities dx/dθ, nx x np.
            let mut sens = DMatrix::<f64>::zeros(if with_jac { nx } else { 0 }, np);
            if with_jac {
                let o = self.off_x0() + ei * nx;
                for i in 0..nx {
                    sens[(i, o + i)] = 1.0;
                }
            }
            for (u, y) in s.u.iter().zip(&s.y) {
                let e = y - &model.c * &x - &model.d * u;
                for j in 0..ny {
                    r[row + j] = e[j] / (self.sy[j] * norm);
                }
                if let Some(jm) = jac.as_mut() {
                    let de = -(&model.c * &sens);
                    for j in 0..ny {
                        let sc = 1.0 / (self.sy[j] * norm);
                        for p in 0..np {
                            jm[(row + j, p)] = de[(j, p)] * sc;
                        }
                    }
                    let mut next = &abar * &sens;
                    for (k, (da, db)) in derivs.iter().enumerate() {
                        let mut col = da * &x + db * u;
                        if matches!(self.gain, Gain::Reset) {
                            // dK/dθ e with K = A C'.
                            col += da * (model.c.transpose() * &e);
                        }
                        for i in 0..nx {
                            next[(i, k)] += col[i];
                        }
                    }
                    if self.k_free() {
                        for i in 0..nx {
                            for j in 0..ny {
                                next[(i, self.off_k() + i * ny + j)] += e[j];
                            }
                        }
                    }
                    sens = next;
                }
                x = &model.a * &x + &model.b * u + &model.k * &e;
                row += ny;
            }
        }
        if !r.iter().all(|v| v.is_finite()) {
            return Err(SysidError::Numerical(
                "non-finite prediction errors (the model diverges on the data)".into(),
            ));
        }
        Ok(Eval { model, r, jac })
    }
}

/// Runs one stage from the parameters `g`, gain `k0` (for a free gain)
/// and initial states `x0`.
fn run_stage(
    prob: &mut Problem,
    stage: Stage,
    g: &GreyBoxParams,
    k0: Option<DMatrix<f64>>,
    x0: &[DVector<f64>],
) -> Result<Search> {
    let (nx, ny) = (prob.nx, prob.ny);
    prob.gain = match stage {
        Stage::EquationError => Gain::Reset,
        Stage::Simulation => Gain::Fixed(DMatrix::zeros(nx, ny)),
        Stage::Prediction | Stage::Noise => Gain::Free,
    };
    prob.g_fixed = *g;
    let mut theta = DVector::zeros(prob.n_params());
    let ga = g.to_array();
    for (k, &i) in prob.phys.iter().enumerate() {
        theta[k] = ga[i].ln();
    }
    if let (true, Some(k0)) = (prob.k_free(), k0) {
        for i in 0..nx {
            for j in 0..ny {
                theta[prob.off_k() + i * ny + j] = k0[(i, j)];
            }
        }
    }
    for (ei, x) in x0.iter().enumerate() {
        let o = prob.off_x0() + ei * nx;
        theta.rows_mut(o, nx).copy_from(x);
    }
    levenberg_marquardt(prob, theta)
}

/// A stable start for a free gain: `K = A C'` (measured states reset to
/// the measurement, the predictor's poles are the actuators') plus, for
/// the disturbance states (the last `ny`, unobserved by `C`), a gain
/// that puts their predictor poles near 0.8.
fn start_gain(m: &InnovationModel, disturbance: bool) -> DMatrix<f64> {
    let mut k = &m.a * m.c.transpose();
    let (nx, ny) = (m.nx(), m.ny());
    if disturbance {
        // d+ = d + K_d e with e ~ ts (d - d_hat): error pole 1 - 0.2.
        for j in 0..ny {
            k[(nx - ny + j, j)] = 0.2 / m.ts;
        }
    }
    k
}

fn series_of(data: &IoData) -> Vec<Series> {
    data.experiments()
        .iter()
        .map(|e| Series {
            u: (0..e.len()).map(|t| e.u.row(t).transpose()).collect(),
            y: (0..e.len()).map(|t| e.y.row(t).transpose()).collect(),
        })
        .collect()
}

impl<'a> Problem<'a> {
    fn new(
        spec: &'a GreyBoxSpec,
        data: &IoData,
        g: GreyBoxParams,
        nx: usize,
        ny: usize,
        series: Vec<Series>,
        sy: &DVector<f64>,
    ) -> Self {
        let (lo, hi) = (spec.lower.to_array(), spec.upper.to_array());
        let phys: Vec<usize> = (0..8).filter(|&i| spec.free[i]).collect();
        let lnb = |v: f64| if v > 0.0 { v.ln() } else { f64::NEG_INFINITY };
        Problem {
            spec,
            ts: data.ts(),
            lo: phys.iter().map(|&i| lnb(lo[i])).collect(),
            hi: phys.iter().map(|&i| lnb(hi[i])).collect(),
            phys,
            gain: Gain::Reset,
            g_fixed: g,
            nx,
            ny,
            series,
            sy: sy.iter().copied().collect(),
            m_total: data.n_samples() * ny,
        }
    }
}

/// The criterion `J` and its analytic gradient (from the sensitivity
/// recursion) at one point: see [`cost_gradient`].
#[derive(Clone, Debug, PartialEq)]
pub struct CostGradient {
    /// `J = 1/(N ny) sum (e_j / s_j)^2` (see the module docs).
    pub cost: f64,
    /// `dJ/dθ` with `θ` = the logarithms of the free parameters (in
    /// [`GreyBoxParams::NAMES`] order), then the entries of `K` row by row
    /// (when a gain is given), then the initial state of every experiment.
    pub gradient: Vec<f64>,
}

/// The grey-box criterion and its gradient at the parameters `g`, the
/// innovation gain `k` (`None`: simulation, `K = 0`) and the initial
/// states `x0` (one per experiment): the quantities the search uses,
/// for checking the gradient against finite differences of `J`.
pub fn cost_gradient(
    data: &IoData,
    spec: &GreyBoxSpec,
    g: &GreyBoxParams,
    k: Option<&DMatrix<f64>>,
    x0: &[DVector<f64>],
) -> Result<CostGradient> {
    let m = grey_box_model(g, spec, data.ts())?;
    let (nx, ny) = (m.nx(), m.ny());
    check_data(data, m.nu(), ny)?;
    if x0.len() != data.experiments().len() {
        return Err(SysidError::dim(
            "initial states (one per experiment)",
            data.experiments().len(),
            x0.len(),
        ));
    }
    if let Some(x) = x0.iter().find(|x| x.len() != nx) {
        return Err(SysidError::dim("initial state", nx, x.len()));
    }
    if let Some(k) = k
        && k.shape() != (nx, ny)
    {
        return Err(SysidError::invalid(format!(
            "K is {}x{}, the model needs {nx}x{ny}",
            k.nrows(),
            k.ncols()
        )));
    }
    let (_, sy) = data.stds();
    let mut prob = Problem::new(spec, data, *g, nx, ny, series_of(data), &sy);
    prob.gain = if k.is_some() {
        Gain::Free
    } else {
        Gain::Fixed(DMatrix::zeros(nx, ny))
    };
    let mut theta = DVector::zeros(prob.n_params());
    let ga = g.to_array();
    for (i, &p) in prob.phys.iter().enumerate() {
        theta[i] = ga[p].ln();
    }
    if let Some(k) = k {
        for i in 0..nx {
            for j in 0..ny {
                theta[prob.off_k() + i * ny + j] = k[(i, j)];
            }
        }
    }
    for (e, x) in x0.iter().enumerate() {
        theta.rows_mut(prob.off_x0() + e * nx, nx).copy_from(x);
    }
    let ev = prob.evaluate(&theta, true)?;
    let jac = ev
        .jac
        .as_ref()
        .ok_or_else(|| SysidError::Numerical("internal: no Jacobian".into()))?;
    Ok(CostGradient {
        cost: cost_of(&ev),
        gradient: (jac.transpose() * &ev.r * 2.0).iter().copied().collect(),
    })
}

/// Outcome of one Levenberg-Marquardt run.
struct Search {
    theta: DVector<f64>,
    eval: Eval,
    initial_cost: f64,
    cost: f64,
    iterations: usize,
    stop: StopReason,
}

impl Search {
    fn summary(&self, stage: Stage) -> StageSummary {
        StageSummary {
            stage,
            iterations: self.iterations,
            initial_cost: self.initial_cost,
            cost: self.cost,
            stop: self.stop,
        }
    }
}

fn cost_of(e: &Eval) -> f64 {
    e.r.norm_squared()
}

fn levenberg_marquardt(prob: &Problem, theta0: DVector<f64>) -> Result<Search> {
    let set = &prob.spec.settings;
    let mut theta = theta0;
    let mut eval = prob.evaluate(&theta, true)?;
    let initial_cost = cost_of(&eval);
    let mut cost = initial_cost;
    let mut mu = 1e-3;
    let mut iterations = 0;
    let mut stop = StopReason::MaxIterations;
    // A free gain keeps the predictor stable (it starts from K = A C',
    // whose predictor poles are the actuators').
    let limit = 1.0 - 1e-6;
    let nphys = prob.phys.len();
    while iterations < set.max_iterations {
        iterations += 1;
        let jac = eval.jac.as_ref().ok_or_else(|| {
            SysidError::Numerical("internal: Jacobian missing in the grey-box search".into())
        })?;
        let h = jac.transpose() * jac;
        let mut h = h;
        let mut g = jac.transpose() * &eval.r;
        // Active bounds: a log parameter on its bound whose descent
        // direction points outward is held (projected Levenberg-Marquardt).
        for k in 0..nphys {
            let at_hi = theta[k] >= prob.hi[k] && g[k] < 0.0;
            let at_lo = theta[k] <= prob.lo[k] && g[k] > 0.0;
            if at_hi || at_lo {
                g[k] = 0.0;
                h.row_mut(k).fill(0.0);
                h.column_mut(k).fill(0.0);
                h[(k, k)] = 1.0;
            }
        }
        if g.amax() <= set.gradient_tolerance * cost.max(f64::MIN_POSITIVE) {
            stop = StopReason::GradientTolerance;
            break;
        }
        let np = theta.len();
        let hmax = h.diagonal().amax();
        let dscale: Vec<f64> = (0..np)
            .map(|i| h[(i, i)].max(1e-12 * hmax).max(1e-300))
            .collect();
        let mut accepted = None;
        while mu < 1e14 {
            let mut lhs = h.clone();
            for i in 0..np {
                lhs[(i, i)] += mu * dscale[i];
            }
            let Some(ch) = lhs.cholesky() else {
                mu *= 10.0;
                continue;
            };
            let step = ch.solve(&(-&g));
            let mut trial = &theta + &step;
            // Bounds: clamp the log parameters.
            for k in 0..nphys {
                trial[k] = trial[k].clamp(prob.lo[k], prob.hi[k]);
            }
            let ok = match prob.evaluate(&trial, false) {
                Ok(e)
                    if prob.k_free()
                        && spectral_radius(&(&e.model.a - &e.model.k * &e.model.c)) > limit =>
                {
                    None
                }
                Ok(e) => Some(e),
                // No hover trim, invalid parameter, divergence: reject.
                Err(_) => None,
            };
            if let Some(e) = ok {
                let c = cost_of(&e);
                if c < cost {
                    mu = (mu / 5.0).max(1e-12);
                    accepted = Some((trial, c));
                    break;
                }
            }
            mu *= 5.0;
        }
        let Some((trial, c_new)) = accepted else {
            stop = StopReason::NoProgress;
            break;
        };
        let rel = (cost - c_new) / cost;
        let step_norm = (&trial - &theta).norm();
        theta = trial;
        cost = c_new;
        eval = prob.evaluate(&theta, true)?;
        if rel < set.cost_tolerance {
            stop = StopReason::CostTolerance;
            break;
        }
        if step_norm < set.step_tolerance * (1.0 + theta.norm()) {
            stop = StopReason::StepTolerance;
            break;
        }
    }
    Ok(Search {
        theta,
        eval,
        initial_cost,
        cost,
        iterations,
        stop,
    })
}

fn check_data(data: &IoData, nu: usize, ny: usize) -> Result<()> {
    if data.nu() != nu {
        return Err(SysidError::dim(
            "data inputs vs grey-box model",
            nu,
            data.nu(),
        ));
    }
    if data.ny() != ny {
        return Err(SysidError::dim(
            "data outputs vs grey-box model",
            ny,
            data.ny(),
        ));
    }
    for (ei, e) in data.experiments().iter().enumerate() {
        for (what, m, names) in [
            ("input", &e.u, data.input_names()),
            ("output", &e.y, data.output_names()),
        ] {
            for t in 0..m.nrows() {
                for j in 0..m.ncols() {
                    if !m[(t, j)].is_finite() {
                        return Err(SysidError::NonFinite {
                            what: names
                                .get(j)
                                .cloned()
                                .unwrap_or_else(|| format!("{what} {j}")),
                            experiment: ei,
                            sample: t,
                        });
                    }
                }
            }
        }
    }
    Ok(())
}

/// The initial guess, or (when it cannot hover and `k_tau` is free) the
/// guess with `k_tau` halved until it can.
fn feasible_start(
    initial: &GreyBoxParams,
    spec: &GreyBoxSpec,
    ts: f64,
) -> Result<(GreyBoxParams, bool)> {
    let first = match grey_box_model(initial, spec, ts) {
        Ok(_) => return Ok((*initial, false)),
        Err(e) => e,
    };
    let ik = 4; // k_tau
    if spec.free[ik] {
        let mut g = *initial;
        for _ in 0..60 {
            g.k_tau *= 0.5;
            if g.k_tau < spec.lower.k_tau {
                break;
            }
            if grey_box_model(&g, spec, ts).is_ok() {
                return Ok((g, true));
            }
        }
    }
    Err(SysidError::invalid(format!(
        "the initial grey-box parameters give no model ({first}){}",
        if spec.free[ik] {
            "; halving k_tau did not help"
        } else {
            ""
        }
    )))
}

/// The thrust and drag constants `k_t`, `k_tau` at which the aircraft of
/// `base` with the other parameters of `g` hovers at the measured
/// operating point `u0 = [pwm1, pwm2, pwm3, servo]` (us): the mean ESC
/// pulse is the hover throttle (rotor speed, hence `k_t = T0 / w0^2` with
/// the known mass) and the servo pulse the tilt that cancels the rotors'
/// reaction torque (hence `k_tau / k_t`). Inertias and actuator constants
/// do not enter the trim, so this is independent of them.
///
/// A closed-form start (`3 k_t w0^2 = m g`, `3 k_tau = k_t l sin(alpha0)`)
/// polished by a damped Newton iteration on the full trim
/// ([`kestrel_tricopter_model::Tricopter::trim_hover`]) in log scale to
/// `1e-6` us. Errors for non-finite pulses, a throttle at or below
/// 1000 us, or no convergence.
pub fn thrust_and_drag_from_trim(
    base: &Params,
    g: &GreyBoxParams,
    u0: &[f64; 4],
) -> Result<GreyBoxParams> {
    if !u0.iter().all(|v| v.is_finite()) {
        return Err(SysidError::invalid(format!(
            "operating point {u0:?} is not finite"
        )));
    }
    let thr = (u0[0] + u0[1] + u0[2]) / 3.0;
    let w0 = base.rotor_speed_for_pwm(thr);
    if w0 <= 0.0 {
        return Err(SysidError::invalid(format!(
            "operating point throttle {thr} us gives no rotor speed"
        )));
    }
    let alpha = base.servo_gain * (u0[3] - base.servo_center);
    let mut out = *g;
    out.k_t = base.mass * base.gravity / (3.0 * w0 * w0);
    out.k_tau = (out.k_t * base.arm_length * alpha.sin().abs() / 3.0).max(1e-6 * out.k_t);
    let resid = |kt: f64, ktau: f64| -> Option<[f64; 2]> {
        let mut q = *g;
        q.k_t = kt;
        q.k_tau = ktau;
        let model = kestrel_tricopter_model::Tricopter::new(q.apply(base)).ok()?;
        let t = model.trim_hover().ok()?;
        Some([t.throttle - thr, t.input[3] - u0[3]])
    };
    let mut z = [out.k_t.ln(), out.k_tau.ln()];
    let fail = || {
        SysidError::invalid(format!(
            "no k_t, k_tau make the aircraft hover at the operating point {u0:?}"
        ))
    };
    let mut f = resid(z[0].exp(), z[1].exp()).ok_or_else(fail)?;
    for _ in 0..50 {
        if f[0].abs().max(f[1].abs()) < 1e-6 {
            out.k_t = z[0].exp();
            out.k_tau = z[1].exp();
            return Ok(out);
        }
        let h = 1e-6;
        let mut jac = [[0.0; 2]; 2];
        for c in 0..2 {
            let mut zp = z;
            let mut zm = z;
            zp[c] += h;
            zm[c] -= h;
            let fp = resid(zp[0].exp(), zp[1].exp()).ok_or_else(fail)?;
            let fm = resid(zm[0].exp(), zm[1].exp()).ok_or_else(fail)?;
            for r in 0..2 {
                jac[r][c] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
        let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
        if !(det.abs() > 0.0 && det.is_finite()) {
            return Err(fail());
        }
        let step = [
            -(jac[1][1] * f[0] - jac[0][1] * f[1]) / det,
            -(-jac[1][0] * f[0] + jac[0][0] * f[1]) / det,
        ];
        let mut s = 1.0;
        loop {
            let zt = [z[0] + s * step[0], z[1] + s * step[1]];
            if let Some(ft) = resid(zt[0].exp(), zt[1].exp())
                && ft[0].abs().max(ft[1].abs()) < f[0].abs().max(f[1].abs())
            {
                z = zt;
                f = ft;
                break;
            }
            s *= 0.5;
            if s < 1e-6 {
                return Err(fail());
            }
        }
    }
    Err(fail())
}

/// Estimates the physical parameters of the tricopter's linearised rate
/// model from input/output data (deviations from the operating point) by
/// the prediction-error method (see the module docs).
///
/// Errors: non-finite data, data columns that do not match the model
/// (`spec.inputs`: 4 PWM or 3 virtual inputs; outputs `p, q, r`), too few
/// samples, a non-positive or non-finite initial parameter, bounds that
/// do not hold the initial value, no free parameter, a free parameter the
/// model does not depend on (actuator constants with
/// [`RateModelKind::Rates`]), an initial guess that cannot hover.
pub fn estimate_grey_box(
    data: &IoData,
    spec: &GreyBoxSpec,
    initial: &GreyBoxParams,
) -> Result<GreyBoxReport> {
    let ts = data.ts();
    let init = initial.to_array();
    let (lo, hi) = (spec.lower.to_array(), spec.upper.to_array());
    for i in 0..8 {
        let name = GreyBoxParams::NAMES[i];
        if !(init[i].is_finite() && init[i] > 0.0) {
            return Err(SysidError::invalid(format!(
                "initial grey-box parameter {name} = {} must be positive and finite",
                init[i]
            )));
        }
        if lo[i].is_nan() || hi[i].is_nan() || lo[i] < 0.0 || hi[i] <= lo[i] {
            return Err(SysidError::invalid(format!(
                "bounds of {name} [{}, {}] must satisfy 0 <= lower < upper",
                lo[i], hi[i]
            )));
        }
        if spec.free[i] && !(init[i] >= lo[i] && init[i] <= hi[i]) {
            return Err(SysidError::invalid(format!(
                "initial {name} = {} is outside its bounds [{}, {}]",
                init[i], lo[i], hi[i]
            )));
        }
    }
    let phys: Vec<usize> = (0..8).filter(|&i| spec.free[i]).collect();
    if phys.is_empty() {
        return Err(SysidError::invalid("no free grey-box parameter"));
    }
    if let (RateModelKind::Rates, Some(&i)) = (spec.kind, phys.iter().find(|&&i| i >= 5)) {
        return Err(SysidError::invalid(format!(
            "{} does not enter the rate model without actuators (RateModelKind::Rates): fix it",
            GreyBoxParams::NAMES[i]
        )));
    }
    // The model's shape (the initial guess may not hover; the base does).
    let probe = grey_box_model(initial, spec, ts)
        .or_else(|_| grey_box_model(&GreyBoxParams::from_params(&spec.base), spec, ts))?;
    let (nx, nu, ny) = (probe.nx(), probe.nu(), probe.ny());
    check_data(data, nu, ny)?;
    let (start, start_adjusted, spec) = match spec.operating_point {
        Some(u0) => {
            let g = thrust_and_drag_from_trim(&spec.base, initial, &u0)?;
            let mut fixed = spec.clone();
            fixed.free[3] = false;
            fixed.free[4] = false;
            (g, false, std::borrow::Cow::Owned(fixed))
        }
        None => {
            let (g, adj) = feasible_start(initial, spec, ts)?;
            (g, adj, std::borrow::Cow::Borrowed(spec))
        }
    };
    let spec: &GreyBoxSpec = &spec;
    let phys: Vec<usize> = (0..8).filter(|&i| spec.free[i]).collect();
    if phys.is_empty() {
        return Err(SysidError::invalid("no free grey-box parameter"));
    }
    let (_, sy) = data.stds();
    for j in 0..ny {
        if sy[j].partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return Err(SysidError::ConstantOutput {
                name: data.output_names()[j].clone(),
            });
        }
    }
    let series = series_of(data);
    let k_free = spec.focus == GreyBoxFocus::Prediction;
    let np = phys.len() + if k_free { nx * ny } else { 0 } + nx * series.len();
    let m_total = data.n_samples() * ny;
    let shortest = series.iter().map(|s| s.u.len()).min().unwrap_or(0);
    if m_total < 2 * np || shortest < nx + 1 {
        return Err(SysidError::TooFewSamples {
            what: format!("grey-box PEM with {np} parameters (order {nx})"),
            needed: (2 * np).div_ceil(ny).max(nx + 1),
            found: data.n_samples(),
        });
    }
    let mut prob = Problem::new(spec, data, start, nx, ny, series, &sy);
    let mut stages = Vec::new();
    let mut current = start;
    let mut x0: Vec<DVector<f64>> = data
        .experiments()
        .iter()
        .map(|e| DVector::from_fn(nx, |i, _| if i < ny { e.y[(0, i)] } else { 0.0 }))
        .collect();
    if spec.settings.equation_error_start {
        let s = run_stage(&mut prob, Stage::EquationError, &current, None, &x0)?;
        current = prob.params_of(&s.theta);
        x0 = prob.x0s_of(&s.theta);
        stages.push(s.summary(Stage::EquationError));
    }
    let main = match spec.focus {
        GreyBoxFocus::Prediction => {
            let m = grey_box_model(&current, spec, ts)?;
            run_stage(
                &mut prob,
                Stage::Prediction,
                &current,
                Some(start_gain(&m, spec.disturbance)),
                &x0,
            )?
        }
        GreyBoxFocus::Simulation | GreyBoxFocus::SimulationThenNoise => {
            let m = grey_box_model(&current, spec, ts)?;
            x0 = data
                .experiments()
                .iter()
                .map(|e| estimate_x0_simulation(&m, &e.u, &e.y))
                .collect::<Result<_>>()?;
            run_stage(&mut prob, Stage::Simulation, &current, None, &x0)?
        }
    };
    let main_stage = if spec.focus == GreyBoxFocus::Prediction {
        Stage::Prediction
    } else {
        Stage::Simulation
    };
    stages.push(main.summary(main_stage));
    let estimate = prob.params_of(&main.theta);
    let std_errors = standard_errors(&prob, &main.eval);
    let (iterations, stop) = (main.iterations, main.stop);
    let mut model = main.eval.model.clone();
    let mut cost = main.cost;
    x0 = prob.x0s_of(&main.theta);
    if spec.focus == GreyBoxFocus::SimulationThenNoise {
        prob.phys.clear();
        prob.lo.clear();
        prob.hi.clear();
        let s2 = run_stage(
            &mut prob,
            Stage::Noise,
            &estimate,
            Some(start_gain(&model, spec.disturbance)),
            &x0,
        )?;
        stages.push(s2.summary(Stage::Noise));
        model = s2.eval.model.clone();
        cost = s2.cost;
        x0 = prob.x0s_of(&s2.theta);
    }
    let est = estimate.to_array();
    let st = start.to_array();
    let mut parameters = Vec::with_capacity(8);
    let mut k = 0;
    for i in 0..8 {
        let se = if spec.free[i] {
            let s = std_errors.as_ref().and_then(|v| v.get(k).copied());
            k += 1;
            s.map(|s| s * est[i])
        } else {
            None
        };
        parameters.push(ParameterEstimate {
            name: GreyBoxParams::NAMES[i],
            free: spec.free[i],
            initial: init[i],
            start: st[i],
            estimate: est[i],
            std_error: se,
        });
    }
    let fit = validate(&model, data, &spec.settings.horizons)?;
    Ok(GreyBoxReport {
        estimate,
        initial: *initial,
        start,
        start_adjusted,
        from_operating_point: spec.operating_point.is_some(),
        parameters,
        model,
        x0,
        initial_cost: stages.first().map(|s| s.initial_cost).unwrap_or(cost),
        cost,
        stages,
        iterations,
        stop,
        fit,
    })
}

/// Standard errors of the free log parameters (in `prob.phys` order):
/// `cov = (Ψ' Σ^-1 Ψ)^-1` with `Σ` the per-output residual variance.
fn standard_errors(prob: &Problem, eval: &Eval) -> Option<Vec<f64>> {
    let jac = eval.jac.as_ref()?;
    let ny = prob.ny;
    let m = prob.m_total;
    let norm = (m as f64).sqrt();
    // Unscaled residual variance per output.
    let mut var = vec![0.0; ny];
    for (row, v) in eval.r.iter().enumerate() {
        let j = row % ny;
        var[j] += (v * prob.sy[j] * norm).powi(2);
    }
    let n = (m / ny) as f64;
    for v in &mut var {
        *v /= n;
    }
    // Rows weighed: de/dθ / sigma_j = dr/dθ * s_j * norm / sigma_j.
    let mut w = jac.clone();
    for row in 0..m {
        let j = row % ny;
        let f = prob.sy[j] * norm / var[j].sqrt().max(f64::MIN_POSITIVE);
        w.row_mut(row).scale_mut(f);
    }
    let info = w.transpose() * w;
    // Jacobi scaling before the factorisations: the information of
    // log parameters, gains and initial states differs by many decades.
    let d: Vec<f64> = (0..info.nrows())
        .map(|i| 1.0 / info[(i, i)].max(f64::MIN_POSITIVE).sqrt())
        .collect();
    let scaled = DMatrix::from_fn(info.nrows(), info.ncols(), |i, j| {
        info[(i, j)] * d[i] * d[j]
    });
    // Marginal covariance of the physical parameters: the Schur complement
    // of the nuisance block (gain, initial states; pseudo-inverted, since
    // an initial state of a mode the data hardly see is nearly free).
    let p = prob.phys.len();
    let q = scaled.nrows() - p;
    let ipp = scaled.view((0, 0), (p, p));
    let ipn = scaled.view((0, p), (p, q));
    let inn = scaled.view((p, p), (q, q)).into_owned();
    let schur = ipp - ipn * crate::linalg::pinv(&inn) * ipn.transpose();
    let cov = schur.cholesky()?.inverse();
    (0..p)
        .map(|k| {
            let v = cov[(k, k)] * d[k] * d[k];
            (v.is_finite() && v >= 0.0).then(|| v.sqrt())
        })
        .collect()
}
