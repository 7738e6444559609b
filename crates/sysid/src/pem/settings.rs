//! What [`pem`](crate::pem()) fits and how: the focus, the
//! criterion and the search settings.

/// What the criterion measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Focus {
    /// One-step prediction errors of the innovation form; `K` is estimated.
    #[default]
    Prediction,
    /// Simulation (output) errors: `K = 0` is fixed (output-error model).
    Simulation,
}

/// How the prediction errors of several outputs are weighed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Criterion {
    /// `det` of the residual covariance (maximum likelihood for Gaussian
    /// innovations, MATLAB's default): minimised by Gauss-Newton on
    /// `trace(W E E')` with `W` the inverse residual covariance, updated
    /// at every iteration.
    Determinant,
    /// `trace` of the residual covariance of the outputs scaled to unit variance.
    #[default]
    Trace,
    /// The sum of the root-mean-square errors of every output (of the
    /// outputs scaled to unit variance) and, with
    /// [`PemSettings::horizon`] `h > 1`, of every prediction step
    /// `1..=h`: up to the normalisation, the mean fit (4.11)/(4.12) over
    /// outputs and steps that the validation tables report. The trace
    /// weighs squared errors, so the outputs and steps the model predicts
    /// worst dominate it; a fit criterion values the same relative gain on
    /// every output and step alike. Minimised by iteratively reweighted
    /// Gauss-Newton on `sum_g w_g |e_g|^2` with `w_g = 1 / rms(e_g)`
    /// renewed every iteration, a majorise-minimise scheme (`sqrt` is
    /// concave), so every accepted step lowers the sum of the RMS errors.
    Fit,
}

/// Settings of [`pem`](crate::pem()).
#[derive(Clone, Debug, PartialEq)]
pub struct PemSettings {
    /// Prediction or simulation focus.
    pub focus: Focus,
    /// How outputs are weighed.
    pub criterion: Criterion,
    /// Estimate a feed-through `D` (otherwise `D` stays as in the start model).
    pub feedthrough: bool,
    /// Largest number of Levenberg-Marquardt iterations.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Stop when the largest gradient entry (relative to the cost) is below this.
    pub gradient_tolerance: f64,
    /// Stop when the step is shorter than this relative to the parameters.
    pub step_tolerance: f64,
    /// Required stability margin: spectral radii of `A` and `A - KC` at
    /// most `1 - stability_margin`.
    pub stability_margin: f64,
    /// Keep `A, B, C, D` of the start model and estimate only the noise
    /// model `K` (and the initial states) by one-step prediction: the
    /// second stage after a [`Focus::Simulation`] fit. Needs
    /// [`Focus::Prediction`].
    pub fixed_dynamics: bool,
    /// Prediction horizon `h` of [`Focus::Prediction`]: the criterion is
    /// the mean squared error of the `1, 2, ..., h`-step-ahead
    /// predictions together (multi-step focus; `1`: the one-step
    /// criterion, MATLAB's default). The Jacobian stays exact (look-ahead
    /// sensitivities); the work grows about `h`-fold. Must be at least 1,
    /// and 1 with [`Focus::Simulation`].
    pub horizon: usize,
    /// The prediction steps (each in `1..=horizon`) whose errors enter
    /// the criterion; empty: all of `1..=horizon`. For example
    /// `horizon: 5, steps: vec![1, 5]` with [`Criterion::Fit`] fits the
    /// sum of the one-step and five-step fits. The work is that of the
    /// whole horizon.
    pub steps: Vec<usize>,
    /// Weight of the simulation term (`0`: off, the default). With a
    /// positive weight the criterion is the validation tables' shape in
    /// one objective: the prediction errors of the steps above (of the
    /// innovation model with its `K`) together with the simulation
    /// errors of the same `A, B, C, D` (`K = 0`, from an initial state of
    /// its own per experiment, estimated as a parameter and started by
    /// least squares like [`compare`](crate::compare)), the simulation
    /// term weighted by this factor. With [`Criterion::Trace`] the
    /// criterion is `(|e_pred|^2 + w |e_sim|^2) / M` (simulation errors
    /// are usually much larger than one-step errors, so even `w = 1`
    /// leans the fit towards simulation); with [`Criterion::Fit`] it is
    /// the sum of the RMS errors per output and prediction step plus `w`
    /// times the RMS simulation error per output, so `w = 1` counts the
    /// simulation fit like one more prediction step. The simulation
    /// term's Jacobian is the exact one of [`Focus::Simulation`] (`K`
    /// does not enter it). Needs [`Focus::Prediction`], estimated
    /// dynamics (not [`PemSettings::fixed_dynamics`]) and the trace or
    /// fit criterion; must be finite and not negative.
    pub simulation_weight: f64,
    /// Largest spectral radius of `A` (not of the predictor) a trial
    /// model may have. `None` (the default): `1 - stability_margin`, like
    /// the predictor `A - KC`. With [`Focus::Prediction`] only the
    /// predictor has to be stable for the criterion to be defined, so a
    /// radius such as `1.02` lets near-integrating dynamics (body rates
    /// flown in closed loop) settle on the unit circle or just beyond it,
    /// where the one-step and k-step predictions are often better; the
    /// predictor `A - KC` stays within `1 - stability_margin`. A model
    /// with `|eig(A)| >= 1` has no bounded simulation: judge it by its
    /// predictions. Needs the prediction focus without a simulation term
    /// when above 1; must be finite and positive.
    pub max_radius_a: Option<f64>,
}

impl Default for PemSettings {
    fn default() -> Self {
        PemSettings {
            focus: Focus::Prediction,
            criterion: Criterion::Trace,
            feedthrough: false,
            max_iterations: 30,
            cost_tolerance: 1e-5,
            gradient_tolerance: 1e-7,
            step_tolerance: 1e-8,
            stability_margin: 1e-4,
            fixed_dynamics: false,
            horizon: 1,
            steps: Vec::new(),
            simulation_weight: 0.0,
            max_radius_a: None,
        }
    }
}
