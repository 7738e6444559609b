//! `kestrel identify`: a state-space model from a CSV flight log.

use crate::io;
use anyhow::{Context, bail};
use kestrel_sysid::workflow::{
    self, AfterReduction, AutoSelect, IdentifySpec, Lowpass, PemFocus, Segment,
};
use kestrel_sysid::{
    Criterion, CsvColumns, IoData, MatrixEstimate, SysidError, TimeUnit, Weighting,
};
use std::path::PathBuf;

/// Identification method.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Subspace identification only.
    N4sid,
    /// Prediction-error method started from N4SID.
    Pem,
    /// Prediction-error method started from PBSID (closed-loop consistent).
    Pbsid,
    /// Prediction-error method started from a high-order ARX reduced by
    /// balanced truncation (closed-loop consistent).
    Arx,
    /// Prediction-error method started from an ARMAX (Hannan-Rissanen)
    /// reduced by balanced truncation.
    Armax,
}

/// N4SID weighting.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightingArg {
    /// MOESP.
    Moesp,
    /// Canonical variate analysis.
    Cva,
}

/// How N4SID estimates the system matrices.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum N4sidMatricesArg {
    /// A, C from the observability matrix; B, D by output-error least squares.
    OutputError,
    /// A, B, C, D by least squares on the estimated state sequence, K from
    /// its residuals.
    StateRegression,
}

/// PEM criterion focus.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FocusArg {
    /// One-step prediction errors (estimates the Kalman gain K).
    Prediction,
    /// Simulation errors (K = 0).
    Simulation,
    /// Simulation errors for A, B, C (D), then K by one-step prediction
    /// with the dynamics fixed (output-error model plus Kalman predictor).
    SimulationThenNoise,
    /// Multi-step prediction errors (1..--dynamics-horizon steps together)
    /// for A, B, C (D), K, then K alone with the dynamics fixed by the
    /// 1..--pem-horizon-step criterion (simulation and k-step fits of
    /// one model together).
    MultiStepThenNoise,
}

/// How PEM weighs the errors of the outputs (and prediction steps).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CriterionArg {
    /// Sum of squared errors of the outputs scaled to unit variance.
    Trace,
    /// Determinant of the residual covariance (maximum likelihood).
    Determinant,
    /// Sum of the RMS errors per output and prediction step (the mean fit).
    Fit,
}

/// `--prefilter`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrefilterArg {
    /// No pre-filter.
    None,
    /// Chosen from the periodogram.
    Auto,
}

/// `--order`: a number or `auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderArg {
    /// Chosen by cross-validation.
    Auto,
    /// Fixed.
    Fixed(usize),
}

/// Reads `--order`: `auto` or a non-negative integer.
fn parse_order(s: &str) -> Result<OrderArg, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(OrderArg::Auto);
    }
    s.parse::<usize>()
        .map(OrderArg::Fixed)
        .map_err(|_| format!("expected a number or `auto`, found {s:?}"))
}

/// Which part of a flight log `--data` identifies on.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentArg {
    /// Each airborne segment found from the motor level, an experiment.
    Airborne,
    /// The whole log.
    All,
}

/// Unit of the `t` column.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeUnitArg {
    /// Seconds.
    S,
    /// Milliseconds.
    Ms,
}

/// What PEM re-estimates after `--reduce`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AfterReductionArg {
    /// Keep balred's model (its K is a truncation, not an estimate).
    Keep,
    /// Re-estimate K with the reduced A, B, C, D fixed (simulation fit unchanged).
    NoiseModel,
    /// Refine the whole reduced model with the --focus criterion.
    All,
}

/// Identifies a discrete-time innovation-form model `x+ = Ax + B(u-u0) + Ke`,
/// `y - y0 = Cx + D(u-u0) + e` from a CSV log and writes it as
/// `kestrel.ss.v1` (removed offsets as `u0`/`y0`); prints the validation
/// table (simulation fit, k-step fits, persistence baseline, residual tests).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// CSV log(s) with a header row, or flight logs (Betaflight blackbox,
    /// Crazyflie uSD, PX4 ULog: recognised by their first bytes, read as
    /// `kestrel import` does, resampled to --rate), comma separated or
    /// repeated; several files are merged as separate experiments
    /// (flights), numbered 1, 2, ... in the order given (a file with an
    /// `experiment` column, or a flight log with several airborne
    /// segments, adds one experiment per value or segment).
    #[arg(long, value_delimiter = ',', required = true)]
    pub data: Vec<PathBuf>,
    /// Input columns, comma separated (e.g. pwm1,pwm2,pwm3,servo); needed
    /// for a CSV. For a flight log: signals as `kestrel import --inputs`
    /// takes them (default: the format's motor commands).
    #[arg(long, value_delimiter = ',')]
    pub inputs: Vec<String>,
    /// Output columns, comma separated (e.g. p,q,r); needed for a CSV. For
    /// a flight log: as `kestrel import --outputs` (default: the body
    /// rates p, q, r in rad/s).
    #[arg(long, value_delimiter = ',')]
    pub outputs: Vec<String>,
    /// Flight logs only: the rate in Hz of the uniform grid the log's
    /// streams are averaged onto (as `kestrel import --rate`); default 50.
    #[arg(long)]
    pub rate: Option<f64>,
    /// Flight logs only: identify on the airborne segments (default) or on
    /// the whole log.
    #[arg(long, value_enum)]
    pub segment: Option<SegmentArg>,
    /// Estimation intervals `start:end,...` in seconds of the `t` column
    /// (row indices when there is none), each optionally prefixed `N@` to
    /// take it from experiment N only (e.g. `2@108.9:165.8`); default: all data.
    #[arg(long)]
    pub estimate: Option<String>,
    /// Validation intervals (same syntax); default: the estimation data.
    #[arg(long)]
    pub validate: Option<String>,
    /// Model order, or `auto` (the default): chosen by blocked
    /// cross-validation inside the estimation data among 1..--max-order.
    /// At most 100, and no more model parameters than output values in
    /// the data (order n has n(n + inputs + 2 outputs) + inputs x outputs).
    #[arg(long, value_parser = parse_order)]
    pub order: Option<OrderArg>,
    /// Largest order the automatic choice tries.
    #[arg(long, default_value_t = 8)]
    pub max_order: usize,
    /// Number of consecutive blocks (folds) of the estimation data for the
    /// automatic structure choice.
    #[arg(long, default_value_t = 3)]
    pub folds: usize,
    /// Safety stop of the automatic structure choice in seconds: no new
    /// fold fit starts after it (the candidates done are compared and the
    /// report says the stop fired). The candidates themselves are planned
    /// by --work-budget, so the choice does not depend on the machine.
    #[arg(long, default_value_t = 60.0)]
    pub time_budget: f64,
    /// Work of the automatic structure choice's fold fits, in estimated
    /// PEM-iteration units (samples x free parameters x states^2 x
    /// prediction steps; default 5e10, about 35 s on 2 busy cores): a larger
    /// budget tries more candidates, a smaller one fewer; the report lists
    /// the candidates skipped.
    #[arg(long)]
    pub work_budget: Option<f64>,
    /// Fit the flags as given, without the automatic structure choice
    /// (order suggested from the singular values unless --order N, N4SID
    /// output-error start, one-step PEM unless --focus/--pem-horizon).
    #[arg(long)]
    pub no_auto: bool,
    /// Show the structure choice's progress on standard error even when
    /// it is not a terminal.
    #[arg(long)]
    pub progress: bool,
    /// Reduce the identified model to this order by balanced truncation.
    #[arg(long)]
    pub reduce: Option<usize>,
    /// Keep the DC gain when reducing (singular perturbation).
    #[arg(long)]
    pub match_dc: bool,
    /// What PEM re-estimates on the estimation data after --reduce (with
    /// --method pem), so the residual tests judge an estimated noise model.
    #[arg(long, value_enum, default_value_t = AfterReductionArg::NoiseModel)]
    pub after_reduction: AfterReductionArg,
    /// Identification method (default: pem; given, it fixes the start).
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// N4SID weighting (default: moesp; given, it fixes the start).
    #[arg(long, value_enum)]
    pub weighting: Option<WeightingArg>,
    /// N4SID horizon (block rows); default chosen from the order. With
    /// `--method pbsid`: the past horizon (VARX lags), default 20 (fewer
    /// on a record too short for a VARX of 20 lags); with
    /// `--method arx` or `armax`: the lags of its polynomials, default 10
    /// (at least the order divided by the number of outputs).
    #[arg(long)]
    pub horizon: Option<usize>,
    /// How N4SID estimates the system matrices (default: output-error;
    /// given, it fixes the start).
    #[arg(long, value_enum)]
    pub n4sid_matrices: Option<N4sidMatricesArg>,
    /// PEM focus (default: chosen by cross-validation, prediction with
    /// --no-auto; given, it fixes the focus).
    #[arg(long, value_enum)]
    pub focus: Option<FocusArg>,
    /// Prediction horizon h of the prediction-focus PEM stages: fit the
    /// 1..h-step-ahead predictions together (multi-step focus); 1 is the
    /// one-step criterion. Each PEM iteration's Jacobian (about samples x
    /// h x outputs residuals x parameters) is limited to 1 GiB and 5e10
    /// operations. Default 1; given, it fixes the focus.
    #[arg(long)]
    pub pem_horizon: Option<usize>,
    /// The prediction steps (each in 1..--pem-horizon, comma separated)
    /// whose errors enter the criterion of the prediction-focus PEM stages,
    /// e.g. `--pem-horizon 5 --pem-steps 1,5 --criterion fit` fits the sum
    /// of the 1-step and 5-step fits; default: all of 1..--pem-horizon.
    /// Given, it fixes the focus.
    #[arg(long, value_delimiter = ',')]
    pub pem_steps: Vec<usize>,
    /// Prediction horizon of the dynamics stage of
    /// `--focus multi-step-then-noise` (ignored by the other foci).
    /// Default 10; given, it fixes the focus.
    #[arg(long)]
    pub dynamics_horizon: Option<usize>,
    /// How the PEM stages weigh the errors of the outputs and steps.
    #[arg(long, value_enum, default_value_t = CriterionArg::Trace)]
    pub criterion: CriterionArg,
    /// Estimate a feed-through matrix D. Without this flag the automatic
    /// choice tries D only when its feedback test finds the estimation
    /// data open-loop (on closed-loop logs D learns the controller's
    /// reaction within the sample); the report says which.
    #[arg(long)]
    pub feedthrough: bool,
    /// Largest number of PEM iterations.
    #[arg(long, default_value_t = 30)]
    pub max_iterations: usize,
    /// Black-box virtual model: map the four inputs (motor 1, 2, 3, servo)
    /// through the mixer (3.28) to (U_r, U_p, U_y) with C_r = 1/sqrt(3),
    /// C_p = 2/3, C_y = 1.
    #[arg(long = "virtual")]
    pub virtual_inputs: bool,
    /// Known input operating point to remove (comma separated); default:
    /// the mean of the estimation data.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub u0: Option<Vec<f64>>,
    /// Known output offset (e.g. gyro bias) to remove; default: the mean of
    /// the estimation data.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub y0: Option<Vec<f64>>,
    /// Zero-phase Butterworth low-pass cut-off in rad/s applied to inputs
    /// and outputs (bilinear with pre-warping, forward-backward).
    #[arg(long)]
    pub lowpass: Option<f64>,
    /// Vibration pre-filter: `auto` looks for a narrow peak in the
    /// outputs' periodogram above a fifth of Nyquist (at least 20 x the
    /// median power) and low-passes inputs and outputs (2nd order,
    /// forward-backward) at 0.6 x its frequency; `none` (default) does
    /// not. Ignored with --lowpass.
    #[arg(long, value_enum, default_value_t = PrefilterArg::None)]
    pub prefilter: PrefilterArg,
    /// Order of the low-pass filter.
    #[arg(long, default_value_t = 2)]
    pub lowpass_order: usize,
    /// Sample time in seconds: required when the file has no `t` column;
    /// with one, it must agree with the column's step.
    #[arg(long)]
    pub ts: Option<f64>,
    /// Unit of the `t` column. Without this flag `t` is read in seconds
    /// and a step of 1 s or more is refused as implausible (a column in
    /// milliseconds); `--time-unit s` accepts any step.
    #[arg(long, value_enum)]
    pub time_unit: Option<TimeUnitArg>,
    /// Prediction horizons for the k-step fit table.
    #[arg(long, value_delimiter = ',', default_values_t = vec![1usize, 5])]
    pub horizons: Vec<usize>,
    /// Write the model resampled to this rate in Hz (identification
    /// stays at the data's rate, e.g. a 500 Hz log, the model is for a
    /// 50 Hz controller): the rates' ratio must be an integer m; A^m,
    /// (I + A + ... + A^(m-1)) B, C, D exactly for inputs held over m
    /// samples, K as A^(m-1) K. The fit table stays at the data's rate.
    #[arg(long)]
    pub model_rate: Option<f64>,
    /// Output model file (default: standard output, table on standard error).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

impl Args {
    /// The order the flags fix (`--order N`).
    fn fixed_order(&self) -> Option<usize> {
        match self.order {
            Some(OrderArg::Fixed(n)) => Some(n),
            Some(OrderArg::Auto) | None => None,
        }
    }

    /// The automatic structure choice: every dimension no flag fixes.
    fn auto_select(&self) -> Option<AutoSelect> {
        if self.no_auto {
            return None;
        }
        Some(AutoSelect {
            order: self.fixed_order().is_none(),
            max_order: self.max_order,
            start: self.method.is_none()
                && self.weighting.is_none()
                && self.n4sid_matrices.is_none(),
            focus: self.focus.is_none()
                && self.pem_horizon.is_none()
                && self.pem_steps.is_empty()
                && self.dynamics_horizon.is_none(),
            folds: self.folds,
            time_budget: self.time_budget,
            work_budget: self
                .work_budget
                .unwrap_or(AutoSelect::default().work_budget),
            ..AutoSelect::default()
        })
    }
}

/// Runs the command: the library's [`kestrel_sysid::workflow::identify`]
/// with the flags as its [`IdentifySpec`].
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace.check(&[args.out.as_deref()])?;
    for (flag, v) in [
        ("--time-budget", Some(args.time_budget)),
        ("--work-budget", args.work_budget),
    ] {
        if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
            bail!("{flag} must be a positive number, got {v}");
        }
    }
    if args.max_order == 0 {
        bail!("--max-order must be at least 1 (the largest order the automatic choice tries)");
    }
    let mut cols = CsvColumns::new(&[], &[]);
    cols.inputs = args.inputs.clone();
    cols.outputs = args.outputs.clone();
    cols.ts = args.ts;
    cols.time_unit = match args.time_unit {
        Some(TimeUnitArg::Ms) => TimeUnit::Milliseconds,
        Some(TimeUnitArg::S) | None => TimeUnit::Seconds,
    };
    let files = args
        .data
        .iter()
        .map(|p| read_data(&args, &cols, p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let data = if files.len() == 1 {
        files.into_iter().next().context("no --data")?
    } else {
        IoData::merge(&files).context("merging the --data files")?
    };
    if args.virtual_inputs && data.nu() != 4 {
        bail!(
            "--virtual needs four inputs (motor 1, motor 2, motor 3, servo), found {}",
            data.nu()
        );
    }
    let parse = |s: &Option<String>, what: &str| -> anyhow::Result<Vec<Segment>> {
        Ok(s.as_deref()
            .map(|t| Segment::parse_list(t).with_context(|| format!("--{what}")))
            .transpose()?
            .unwrap_or_default())
    };
    let raw_nu = data.nu();
    if let Some(u0) = args.u0.as_ref().filter(|v| v.len() != raw_nu) {
        bail!("--u0 needs {raw_nu} values, found {}", u0.len());
    }
    if let Some(y0) = args.y0.as_ref().filter(|v| v.len() != data.ny()) {
        bail!("--y0 needs {} values, found {}", data.ny(), y0.len());
    }
    check_horizon(&args, data.ny())?;
    check_lowpass(&args, &data)?;
    let estimate = parse(&args.estimate, "estimate")?;
    let validate = parse(&args.validate, "validate")?;
    note_beyond_samples(&data, &estimate, "estimate");
    note_beyond_samples(&data, &validate, "validate");
    let spec = IdentifySpec {
        estimate,
        validate,
        order: args.fixed_order(),
        reduce: args.reduce,
        match_dc: args.match_dc,
        after_reduction: match args.after_reduction {
            AfterReductionArg::Keep => AfterReduction::Keep,
            AfterReductionArg::NoiseModel => AfterReduction::NoiseModel,
            AfterReductionArg::All => AfterReduction::All,
        },
        method: match args.method.unwrap_or(Method::Pem) {
            Method::N4sid => workflow::Method::N4sid,
            Method::Pem | Method::Pbsid | Method::Arx | Method::Armax => workflow::Method::Pem,
        },
        start: match args.method {
            Some(Method::Pbsid) => workflow::Start::Pbsid,
            Some(Method::Arx) => workflow::Start::Arx,
            Some(Method::Armax) => workflow::Start::Armax,
            Some(Method::N4sid | Method::Pem) | None => workflow::Start::N4sid,
        },
        weighting: match args.weighting.unwrap_or(WeightingArg::Moesp) {
            WeightingArg::Moesp => Weighting::Moesp,
            WeightingArg::Cva => Weighting::Cva,
        },
        horizon: args.horizon,
        n4sid_matrices: match args.n4sid_matrices.unwrap_or(N4sidMatricesArg::OutputError) {
            N4sidMatricesArg::OutputError => MatrixEstimate::OutputError,
            N4sidMatricesArg::StateRegression => MatrixEstimate::StateRegression,
        },
        focus: match args.focus.unwrap_or(FocusArg::Prediction) {
            FocusArg::Prediction => PemFocus::Prediction,
            FocusArg::Simulation => PemFocus::Simulation,
            FocusArg::SimulationThenNoise => PemFocus::SimulationThenNoise,
            FocusArg::MultiStepThenNoise => PemFocus::MultiStepThenNoise {
                horizon: args.dynamics_horizon.unwrap_or(10),
            },
        },
        pem_horizon: args.pem_horizon.unwrap_or(1),
        pem_steps: args.pem_steps.clone(),
        criterion: match args.criterion {
            CriterionArg::Trace => Criterion::Trace,
            CriterionArg::Determinant => Criterion::Determinant,
            CriterionArg::Fit => Criterion::Fit,
        },
        feedthrough: args.feedthrough,
        max_iterations: args.max_iterations,
        input_map: args
            .virtual_inputs
            .then(kestrel_tricopter::ident::virtual_input_map),
        u0: args.u0.clone(),
        y0: args.y0.clone(),
        lowpass: args.lowpass.map(|cutoff| Lowpass {
            order: args.lowpass_order,
            cutoff,
        }),
        prefilter: match args.prefilter {
            PrefilterArg::None => workflow::Prefilter::None,
            PrefilterArg::Auto => workflow::Prefilter::Auto,
        },
        horizons: args.horizons.clone(),
        auto: args.auto_select(),
        arx_baseline: Some(2..=10),
    };
    let shown = ChoiceProgress::new(args.progress);
    let report =
        workflow::identify_with_progress(&data, &spec, &|p| shown.update(p)).map_err(|e| {
            if matches!(e, SysidError::ConstantInput { .. }) {
                anyhow::anyhow!("identification: {e}. {}", constant_input_hint(&args, &data))
            } else {
                crate::guards::sysid(e).context("identification")
            }
        })?;
    drop(shown);
    let (ss, resampled) = match args.model_rate {
        Some(hz) => {
            if !(hz.is_finite() && hz > 0.0) {
                bail!("--model-rate must be a positive number of Hz, got {hz}");
            }
            let m = workflow::rate_factor(report.ts, 1.0 / hz).context("--model-rate")?;
            let model = workflow::resample_model(&report.model, m).context("--model-rate")?;
            let note = format!(
                "model resampled from {:.6} Hz to {hz} Hz (factor {m}: A^{m}, (I + ... + A^{}) B, C, D, K -> A^{} K)\n",
                1.0 / report.ts,
                m - 1,
                m - 1
            );
            let ss = model.to_ss_model(
                Some(&report.offsets.u0),
                Some(&report.offsets.y0),
                Some(&report.input_names),
                Some(&report.output_names),
            )?;
            (ss, note)
        }
        None => (report.to_ss_model()?, String::new()),
    };
    io::write_output(args.out.as_deref(), &ss.to_json_string())?;
    if args.out.is_some() {
        print!("{report}{resampled}");
    } else {
        eprint!("{report}{resampled}");
    }
    Ok(())
}

/// Says on standard error which intervals reach beyond the data's samples:
/// selection takes only their part with samples, so a mistyped end (say
/// `72:930` for `72:93`) would otherwise pass unseen.
fn note_beyond_samples(data: &IoData, segments: &[Segment], what: &str) {
    for s in segments {
        if let Some(span) = s.beyond_samples(data) {
            let (which, whose) = match s.experiment {
                Some(i) => (format!("{}@", i + 1), format!("experiment {}'s", i + 1)),
                None => (String::new(), "the data's".to_string()),
            };
            eprintln!(
                "note: --{what} {which}{}:{} reaches beyond {whose} samples ({:.3}..{:.3}); it takes {:.3}..{:.3}",
                s.interval.start,
                s.interval.end,
                span.first,
                span.last,
                s.interval.start.max(span.first),
                s.interval.end.min(span.last)
            );
        }
    }
}

/// Progress of the identification: a spinner with the structure choice's
/// fits done on a terminal, one line per fit on standard error with
/// `--progress` when it is not one, nothing otherwise.
struct ChoiceProgress {
    /// The spinner (a terminal).
    bar: Option<indicatif::ProgressBar>,
    /// One line per fit (`--progress` without a terminal).
    lines: bool,
}

impl ChoiceProgress {
    fn new(asked: bool) -> Self {
        if crate::progress::enabled() {
            let pb = indicatif::ProgressBar::new_spinner();
            pb.set_style(
                indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
            );
            pb.enable_steady_tick(std::time::Duration::from_millis(200));
            pb.set_message("identifying the model");
            crate::progress::show(&pb);
            ChoiceProgress {
                bar: Some(pb),
                lines: false,
            }
        } else {
            ChoiceProgress {
                bar: None,
                lines: asked,
            }
        }
    }

    fn update(&self, p: &workflow::Progress) {
        let text = format!("structure choice: {}/{} fits ({})", p.done, p.total, p.last);
        if let Some(bar) = &self.bar {
            bar.set_message(text);
        } else if self.lines {
            eprintln!("{text}");
        }
    }
}

impl Drop for ChoiceProgress {
    fn drop(&mut self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// The documented rule for the `t` column's unit: without `--time-unit`
/// and `--ts`, a step of 1 s or more (a 50 Hz log in milliseconds reads
/// as 20 s) is refused; the user states the unit instead of a guess.
/// One `--data` file: a flight log through `kestrel-logs` (by its first
/// bytes), anything else as a CSV with the named columns.
fn read_data(args: &Args, cols: &CsvColumns, p: &std::path::Path) -> anyhow::Result<IoData> {
    if crate::logs::is_flight_log(p) {
        if args.ts.is_some() || args.time_unit.is_some() {
            bail!(
                "{}: a flight log has its own clock; --ts and --time-unit are for CSV files",
                p.display()
            );
        }
        let rate = args.rate.unwrap_or(50.0);
        if !(rate.is_finite() && rate > 0.0) {
            bail!("--rate must be a positive number of Hz, got {rate}");
        }
        let segment = match args.segment {
            Some(SegmentArg::All) => kestrel_logs::SegmentChoice::All,
            Some(SegmentArg::Airborne) | None => kestrel_logs::SegmentChoice::Airborne,
        };
        return crate::logs::load_log_as_iodata(p, &args.inputs, &args.outputs, rate, segment)
            .with_context(|| format!("reading the flight log {}", p.display()));
    }
    if args.rate.is_some() || args.segment.is_some() {
        bail!(
            "{}: --rate and --segment resample flight logs (Betaflight, Crazyflie, PX4 ULog); a CSV is identified at its own rate (use `kestrel import` to resample a log)",
            p.display()
        );
    }
    if args.inputs.is_empty() || args.outputs.is_empty() {
        bail!(
            "{}: --inputs and --outputs must name the CSV's input and output columns",
            p.display()
        );
    }
    let d = IoData::read_csv(p, cols).with_context(|| format!("reading {}", p.display()))?;
    check_time_unit(args, p, &d)?;
    Ok(d)
}

fn check_time_unit(args: &Args, path: &std::path::Path, data: &IoData) -> anyhow::Result<()> {
    if args.time_unit.is_none() && args.ts.is_none() && data.ts() >= 1.0 {
        // `{}` writes every digit of 2e298.
        let ts = if data.ts() < 1e6 {
            format!("{}", data.ts())
        } else {
            format!("{:e}", data.ts())
        };
        bail!(
            "{}: the `t` column steps by {ts} s, implausible for a flight log in seconds: if it is in milliseconds, add --time-unit ms; if the log really is sampled every {ts} s, add --time-unit s",
            path.display(),
        );
    }
    Ok(())
}

/// The largest order whose singular value N4SID shows (the workflow's
/// `max_order`, at least the requested order).
const N4SID_SHOWN_ORDERS: usize = 10;

/// `--horizon` against the orders N4SID examines: it needs horizon x
/// outputs > the largest of them.
fn check_horizon(args: &Args, ny: usize) -> anyhow::Result<()> {
    let Some(h) = args.horizon else {
        return Ok(());
    };
    if matches!(args.method, Some(Method::Arx | Method::Armax)) {
        // The ARX's lags: kestrel-sysid checks them against the order.
        return Ok(());
    }
    let largest = args.fixed_order().unwrap_or(0).max(N4SID_SHOWN_ORDERS);
    if h >= 2 && h * ny > largest {
        return Ok(());
    }
    let why = match args.fixed_order() {
        Some(o) if o > N4SID_SHOWN_ORDERS => format!("--order {o}"),
        Some(o) => format!(
            "the singular values it shows go to order {N4SID_SHOWN_ORDERS}, also with --order {o}"
        ),
        None => format!("the singular values it shows go to order {N4SID_SHOWN_ORDERS}"),
    };
    bail!(
        "--horizon {h} is too short: N4SID needs at least 2 block rows and horizon x outputs > the largest order it examines ({largest}: {why}) with {ny} outputs; use --horizon {} or more, or leave it out",
        (largest / ny + 1).max(2)
    )
}

/// What the sample time suggests about the `t` column.
fn time_hint(data: &IoData) -> String {
    if data.ts() > 1.0 {
        format!(
            " (ts = {} s, read from the `t` column: is it in milliseconds? kestrel expects seconds)",
            data.ts()
        )
    } else {
        String::new()
    }
}

/// `--lowpass` between the lowest frequency the log resolves and Nyquist.
fn check_lowpass(args: &Args, data: &IoData) -> anyhow::Result<()> {
    let Some(cutoff) = args.lowpass else {
        return Ok(());
    };
    let ts = data.ts();
    let nyquist = std::f64::consts::PI / ts;
    let longest = data
        .experiments()
        .iter()
        .map(|e| e.len())
        .max()
        .unwrap_or(0);
    let lowest = 2.0 * std::f64::consts::PI / (longest.max(1) as f64 * ts);
    if !(cutoff.is_finite() && cutoff > 0.0) {
        bail!("--lowpass: the cut-off must be a positive number of rad/s, got {cutoff}");
    }
    if cutoff >= nyquist {
        bail!(
            "--lowpass {cutoff} rad/s is at or above the Nyquist frequency pi/ts = {nyquist:.4} rad/s{}; choose a cut-off below it",
            time_hint(data)
        );
    }
    if cutoff < lowest {
        bail!(
            "--lowpass {cutoff} rad/s is below {lowest:.4} rad/s, the lowest frequency of the log (2 pi / {:.1} s): it would flatten every signal to a constant; choose a cut-off between {lowest:.4} and {nyquist:.4} rad/s (pi/ts)",
            longest as f64 * ts
        );
    }
    Ok(())
}

/// The likely causes of a constant input, from the flags and the data.
fn constant_input_hint(args: &Args, data: &IoData) -> String {
    let mut causes = Vec::new();
    let t = time_hint(data);
    if !t.is_empty() {
        causes.push(format!("the time column's unit{t}"));
    }
    if let Some(c) = args.lowpass {
        causes.push(format!(
            "--lowpass {c} rad/s filtering the variation away (try a higher cut-off)"
        ));
    }
    if args.estimate.is_some() {
        causes.push(
            "the --estimate intervals selecting a stretch where it does not move (e.g. before take-off)"
                .to_string(),
        );
    }
    causes.push("the --inputs column naming a signal that does not vary in this log".to_string());
    format!("Likely causes: {}", causes.join("; "))
}
