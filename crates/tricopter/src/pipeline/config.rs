//! The pipeline's configuration: one struct per section of the TOML file
//! (`crates/cli/kestrel.toml` is the built-in default of `kestrel
//! pipeline`), every key required, unknown keys rejected when
//! deserialised, and a semantic check that names the key of every bad
//! value.

use super::error::{PipelineError, Result};
use serde::Deserialize;

/// Returns the configuration error of `message`, whose first word is the key.
macro_rules! bail {
    ($($arg:tt)*) => {{
        let message = format!($($arg)*);
        return Err(PipelineError::config_message(message));
    }};
}

/// The whole configuration.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Simulated flights.
    pub experiments: Experiments,
    /// Gyro bias, covariance and trim estimation.
    pub sensor: Sensor,
    /// System identification.
    pub identification: Identification,
    /// Stationary Kalman filter.
    pub kalman: Kalman,
    /// MPC problems.
    pub mpc: Mpc,
    /// Explicit MPC.
    pub empc: Empc,
    /// Fast gradient method.
    pub fgm: Fgm,
    /// Table 7.2.
    pub comparison: Comparison,
    /// Closed-loop runs of section 7.7.
    pub closed_loop: ClosedLoop,
    /// Firmware tables.
    pub firmware: Firmware,
    /// Overrides of `--quick`.
    pub quick: Quick,
}

/// `[experiments]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Experiments {
    /// Seconds per flight.
    pub seconds: f64,
    /// Base seed.
    pub seed: u64,
    /// RK4 step (s).
    pub dt: f64,
}

/// `[sensor]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    /// Seconds skipped at the start of the ground experiment.
    pub ground_skip: f64,
    /// Seconds cut from both ends of the hover flight for the trim.
    pub hover_trim: f64,
}

/// One interval of a flight.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Interval {
    /// Flight number (1-4).
    pub flight: u8,
    /// Start (s).
    pub from: f64,
    /// End (s).
    pub to: f64,
}

/// Estimation and validation intervals.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DataSets {
    /// Estimation intervals.
    pub estimate: Vec<Interval>,
    /// Validation intervals.
    pub validate: Vec<Interval>,
}

/// `[identification]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Identification {
    /// PEM order.
    pub order: usize,
    /// Order after balred.
    pub reduced_order: usize,
    /// Keep the DC gain when reducing (leaves a feed-through D).
    pub match_dc: bool,
    /// PEM iteration limit.
    pub pem_max_iterations: usize,
    /// k of the k-step fits.
    pub horizons: Vec<usize>,
    /// Residual correlation lags.
    pub residual_lags: usize,
    /// Black-box data sets.
    pub blackbox: DataSets,
    /// Black-box virtual data sets.
    #[serde(rename = "virtual")]
    pub virtual_: DataSets,
}

/// `[kalman]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Kalman {
    /// Pulse noise standard deviation (us).
    pub input_noise: f64,
    /// Candidate rate noise standard deviations (rad/s per sample).
    pub rate_noise: Vec<f64>,
    /// Candidate gust-state noise standard deviations (rad/s per sample).
    pub gust_noise: Vec<f64>,
    /// Flight on which the noise levels are chosen.
    pub training_flight: u8,
    /// Flight filtered for the plot.
    pub flight: u8,
    /// Plot start (s).
    pub plot_from: f64,
    /// Plot end (s).
    pub plot_to: f64,
}

/// A horizon with its move blocking.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Horizon {
    /// Prediction horizon N.
    pub horizon: usize,
    /// Block lengths (sum N).
    pub blocks: Vec<usize>,
}

/// `[mpc]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Mpc {
    /// Output weight: `q1 * I`, or the diagonal per output.
    pub q1: WeightSpec,
    /// Input weight: `q2 * I`, or the diagonal per input.
    pub q2: WeightSpec,
    /// Bound on |x| in the parameter set.
    pub state_bound: f64,
    /// Bound on the references.
    pub reference_bound: f64,
    /// Offset-free MPC: constant torque disturbances on the rate states
    /// (`DisturbanceModel::OutputStates`), estimated by the Kalman filter;
    /// `theta = [x; d; r; throttle]`.
    pub offset_free: bool,
    /// The thesis-sized problem.
    pub thesis: Horizon,
    /// The larger problem.
    pub larger: Horizon,
}

/// A weight: one number (times the identity) or one entry per diagonal element.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum WeightSpec {
    /// `s * I`.
    Scalar(f64),
    /// A diagonal.
    Diagonal(Vec<f64>),
}

impl WeightSpec {
    /// The entries (one for a scalar).
    pub fn values(&self) -> &[f64] {
        match self {
            WeightSpec::Scalar(v) => std::slice::from_ref(v),
            WeightSpec::Diagonal(v) => v,
        }
    }

    /// As kestrel-mpc's weight.
    pub fn weight(&self) -> kestrel_mpc::Weight {
        match self {
            WeightSpec::Scalar(v) => kestrel_mpc::Weight::Scalar(*v),
            WeightSpec::Diagonal(v) => kestrel_mpc::Weight::Diagonal(v.clone()),
        }
    }
}

impl std::fmt::Display for WeightSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WeightSpec::Scalar(v) => write!(f, "{v} I"),
            WeightSpec::Diagonal(v) => write!(f, "diag{v:?}"),
        }
    }
}

/// `[empc]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Empc {
    /// Also solve the larger problem explicitly.
    pub solve_larger: bool,
    /// Random check points against clarabel.
    pub check_points: usize,
    /// Parameter indices on the slice axes.
    pub slice_axes: [usize; 2],
    /// Plotted ranges.
    pub slice_range: [[f64; 2]; 2],
    /// Throttle of the slice point.
    pub slice_throttle: f64,
}

/// The fast-gradient preconditioner.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum PreconditionerChoice {
    /// No scaling.
    None,
    /// Jacobi.
    Jacobi,
    /// Optimal diagonal (SDP).
    OptimalDiagonal,
}

/// `[fgm]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Fgm {
    /// Preconditioner.
    pub preconditioner: PreconditionerChoice,
    /// Tolerances of the certification table.
    pub eps_table: Vec<f64>,
    /// Largest PWM error (us).
    pub pwm_error: f64,
    /// Random check points against clarabel.
    pub check_points: usize,
}

/// `[comparison]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Comparison {
    /// Initial body rates.
    pub rates: [f64; 3],
    /// Rate references.
    pub reference: [f64; 3],
    /// Throttle (us).
    pub throttle: f64,
    /// Fixed iteration counts.
    pub iterations: Vec<usize>,
}

/// `[closed_loop]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClosedLoop {
    /// Initial body rates.
    pub initial_rates: [f64; 3],
    /// Time of the step (s).
    pub step_time: f64,
    /// Step references.
    pub step: [f64; 3],
    /// Duration (s).
    pub duration: f64,
    /// Noise seed.
    pub seed: u64,
    /// FGM iteration counts of the noisy runs.
    pub fgm_iterations: Vec<usize>,
}

/// Scalar of the firmware tables.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FirmwareScalar {
    /// 32-bit float.
    F32,
    /// Q16 fixed point.
    Q16,
}

/// `[firmware]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Firmware {
    /// Table scalar.
    pub scalar: FirmwareScalar,
}

/// `[quick]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Quick {
    /// Replaces `identification.pem_max_iterations`.
    pub pem_max_iterations: usize,
    /// Replaces `empc.check_points`.
    pub empc_check_points: usize,
    /// Replaces `fgm.check_points`.
    pub fgm_check_points: usize,
    /// Replaces `closed_loop.duration`.
    pub closed_loop_duration: f64,
    /// Replaces `closed_loop.fgm_iterations`.
    pub fgm_iterations: Vec<usize>,
}

impl Config {
    /// The `--quick` variant: the `[quick]` keys replace their full-run keys.
    pub fn quick(mut self) -> Self {
        let q = self.quick.clone();
        self.identification.pem_max_iterations = q.pem_max_iterations;
        self.empc.check_points = q.empc_check_points;
        self.fgm.check_points = q.fgm_check_points;
        self.closed_loop.duration = q.closed_loop_duration;
        self.closed_loop.fgm_iterations = q.fgm_iterations;
        self
    }

    /// Semantic checks; each error names its key.
    pub fn check(&self) -> Result<()> {
        fn pos(v: f64, key: &str) -> Result<()> {
            if !(v.is_finite() && v > 0.0) {
                bail!("{key} = {v}: expected a positive finite number");
            }
            Ok(())
        }
        fn nonneg(v: f64, key: &str) -> Result<()> {
            if !(v.is_finite() && v >= 0.0) {
                bail!("{key} = {v}: expected a finite number >= 0");
            }
            Ok(())
        }
        fn finite(v: &[f64], key: &str) -> Result<()> {
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                bail!("{key}: {x} is not a finite number");
            }
            Ok(())
        }
        let e = &self.experiments;
        pos(e.seconds, "experiments.seconds")?;
        pos(e.dt, "experiments.dt")?;
        let ratio = 0.02 / e.dt;
        if (ratio - ratio.round()).abs() > 1e-9 {
            bail!(
                "experiments.dt = {}: must divide the 0.02 s sample period",
                e.dt
            );
        }
        nonneg(self.sensor.ground_skip, "sensor.ground_skip")?;
        nonneg(self.sensor.hover_trim, "sensor.hover_trim")?;
        if self.sensor.ground_skip >= e.seconds || 2.0 * self.sensor.hover_trim >= e.seconds {
            bail!("sensor.ground_skip / sensor.hover_trim leave no data of experiments.seconds");
        }
        let id = &self.identification;
        if id.order == 0 {
            bail!("identification.order = 0: expected at least 1");
        }
        if id.reduced_order == 0 || id.reduced_order > id.order {
            bail!(
                "identification.reduced_order = {}: expected 1..={} (identification.order)",
                id.reduced_order,
                id.order
            );
        }
        if id.horizons.is_empty() || id.horizons.contains(&0) {
            bail!("identification.horizons: expected a non-empty list of positive integers");
        }
        if id.residual_lags == 0 {
            bail!("identification.residual_lags = 0: expected at least 1");
        }
        for (name, sets) in [("blackbox", &id.blackbox), ("virtual", &id.virtual_)] {
            for (what, list) in [("estimate", &sets.estimate), ("validate", &sets.validate)] {
                let key = format!("identification.{name}.{what}");
                if list.is_empty() {
                    bail!("{key}: expected at least one interval");
                }
                for (i, iv) in list.iter().enumerate() {
                    if !(2..=3).contains(&iv.flight) {
                        bail!(
                            "{key}[{i}].flight = {}: expected 2 (decoupled) or 3 (coupled)",
                            iv.flight
                        );
                    }
                    if !(iv.from.is_finite()
                        && iv.to.is_finite()
                        && 0.0 <= iv.from
                        && iv.from < iv.to)
                    {
                        bail!(
                            "{key}[{i}]: expected 0 <= from < to, found {} .. {}",
                            iv.from,
                            iv.to
                        );
                    }
                    if iv.to > e.seconds {
                        bail!(
                            "{key}[{i}].to = {}: beyond experiments.seconds = {}",
                            iv.to,
                            e.seconds
                        );
                    }
                }
            }
        }
        let k = &self.kalman;
        pos(k.input_noise, "kalman.input_noise")?;
        for (v, key) in [
            (&k.rate_noise, "kalman.rate_noise"),
            (&k.gust_noise, "kalman.gust_noise"),
        ] {
            if v.is_empty() {
                bail!("{key}: expected at least one value");
            }
            for x in v {
                pos(*x, key)?;
            }
        }
        if !(1..=4).contains(&k.training_flight) {
            bail!(
                "kalman.training_flight = {}: expected 1..=4",
                k.training_flight
            );
        }
        if !(1..=4).contains(&k.flight) {
            bail!("kalman.flight = {}: expected 1..=4", k.flight);
        }
        if !(k.plot_from.is_finite()
            && k.plot_to.is_finite()
            && 0.0 <= k.plot_from
            && k.plot_from < k.plot_to
            && k.plot_to <= e.seconds)
        {
            bail!(
                "kalman.plot_from / kalman.plot_to = {} / {}: expected 0 <= from < to <= experiments.seconds",
                k.plot_from,
                k.plot_to
            );
        }
        let m = &self.mpc;
        for (w, key, n) in [(&m.q1, "mpc.q1", 3), (&m.q2, "mpc.q2", 4)] {
            let v = w.values();
            if v.len() != 1 && v.len() != n {
                bail!(
                    "{key}: expected a number or a list of {n} numbers, found {} numbers",
                    v.len()
                );
            }
            for x in v {
                pos(*x, key)?;
            }
        }
        pos(m.state_bound, "mpc.state_bound")?;
        pos(m.reference_bound, "mpc.reference_bound")?;
        for (name, h) in [("thesis", &m.thesis), ("larger", &m.larger)] {
            if h.horizon == 0
                || h.blocks.contains(&0)
                || h.blocks.iter().sum::<usize>() != h.horizon
            {
                bail!(
                    "mpc.{name}: blocks {:?} must be positive and add up to horizon = {}",
                    h.blocks,
                    h.horizon
                );
            }
        }
        let x = &self.empc;
        if x.check_points == 0 {
            bail!("empc.check_points = 0: expected at least 1");
        }
        if x.slice_axes[0] == x.slice_axes[1] {
            bail!("empc.slice_axes: the two axes must differ");
        }
        for (i, r) in x.slice_range.iter().enumerate() {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] < r[1]) {
                bail!("empc.slice_range[{i}]: expected [low, high] with low < high");
            }
        }
        pos(x.slice_throttle, "empc.slice_throttle")?;
        let f = &self.fgm;
        if f.eps_table.is_empty() {
            bail!("fgm.eps_table: expected at least one tolerance");
        }
        for v in &f.eps_table {
            pos(*v, "fgm.eps_table")?;
        }
        pos(f.pwm_error, "fgm.pwm_error")?;
        if f.check_points == 0 {
            bail!("fgm.check_points = 0: expected at least 1");
        }
        let c = &self.comparison;
        finite(&c.rates, "comparison.rates")?;
        finite(&c.reference, "comparison.reference")?;
        pos(c.throttle, "comparison.throttle")?;
        if c.iterations.contains(&0) {
            bail!("comparison.iterations: iteration counts must be positive");
        }
        let l = &self.closed_loop;
        finite(&l.initial_rates, "closed_loop.initial_rates")?;
        finite(&l.step, "closed_loop.step")?;
        pos(l.duration, "closed_loop.duration")?;
        if !(l.step_time.is_finite() && l.step_time >= 0.0 && l.step_time < l.duration) {
            bail!(
                "closed_loop.step_time = {}: expected 0 <= step_time < closed_loop.duration = {}",
                l.step_time,
                l.duration
            );
        }
        if l.fgm_iterations.contains(&0) {
            bail!("closed_loop.fgm_iterations: iteration counts must be positive");
        }
        let q = &self.quick;
        pos(q.closed_loop_duration, "quick.closed_loop_duration")?;
        if q.closed_loop_duration <= l.step_time {
            bail!(
                "quick.closed_loop_duration = {}: must exceed closed_loop.step_time = {}",
                q.closed_loop_duration,
                l.step_time
            );
        }
        if q.empc_check_points == 0 || q.fgm_check_points == 0 {
            bail!("quick.empc_check_points / quick.fgm_check_points: expected at least 1");
        }
        if q.fgm_iterations.contains(&0) {
            bail!("quick.fgm_iterations: iteration counts must be positive");
        }
        Ok(())
    }
}
