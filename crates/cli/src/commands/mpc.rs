//! `kestrel mpc`: build the condensed MPC problem of a model and write it
//! as `kestrel.mpqp.v1`.

use crate::io;
use anyhow::{Context, bail};
use kestrel_core::formats::{SsModel, matrix_from_text};
use kestrel_mpc::{Blocking, Bounds, MpcProblem, MpcSettings, Terminal, Weight};
use kestrel_tricopter::{throttle_parameter, tricopter_trim};
use nalgebra::{DMatrix, DVector};
use std::path::{Path, PathBuf};

/// Builds the condensed parametric QP (thesis (6.19)-(6.26), errata
/// applied) of a discrete `kestrel.ss.v1` model and writes it as
/// `kestrel.mpqp.v1` with `theta = [x; r_1..r_ny; throttle]` (for the
/// tricopter `[x; r_roll; r_pitch; r_yaw; throttle]`).
///
/// The tricopter (`--tricopter`, or a model whose inputs are named
/// `pwm1,pwm2,pwm3,servo`): its inputs are bounded by the PWM ranges
/// around its `u0` (motors within 1000-2000 us minus the throttle, the
/// servo within +-300 us of its centre) and the throttle is the last
/// parameter. Other models need `--u-min` and `--u-max` (deviations from
/// `u0`) and have no throttle parameter.
#[derive(clap::Args, Debug)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// Discrete-time model (`kestrel.ss.v1`, `ts > 0`, `D = 0`).
    #[arg(long)]
    pub model: PathBuf,
    /// Prediction horizon N (steps). The condensed problem has blocks x
    /// inputs decision variables, at most 1000 (one block per step without
    /// --blocks), and its build at most 1 GiB and 1e11 operations.
    #[arg(long)]
    pub horizon: usize,
    /// Move-blocking lengths, comma separated, summing to N (default: one
    /// block per step). The thesis's Ns = 1 with N = 2 is `--blocks 2`.
    #[arg(long, value_delimiter = ',')]
    pub blocks: Option<Vec<usize>>,
    /// Output weight Q1: a number (times the identity) or a JSON matrix file.
    #[arg(long, default_value = "1", allow_negative_numbers = true)]
    pub q1: String,
    /// Input weight Q2: a number (times the identity) or a JSON matrix file.
    #[arg(long, default_value = "1e-4", allow_negative_numbers = true)]
    pub q2: String,
    /// Terminal weight: `lq` (Riccati solution, thesis (7.18)-(7.19)),
    /// `q1` (Q1N = Q1), or a JSON matrix file: ny x ny is the output weight
    /// Q1N, nx x nx (when nx != ny) the state weight on x_N - C^+ r.
    #[arg(long, default_value = "lq")]
    pub terminal: String,
    /// Lower input bounds, comma separated, as deviations from `u0`
    /// (required for models other than the tricopter's; not with `--tricopter`).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub u_min: Option<Vec<f64>>,
    /// Upper input bounds, comma separated, as deviations from `u0`.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub u_max: Option<Vec<f64>>,
    /// Parameter box of the states written to the file: |x_i| <= x-max.
    #[arg(long, default_value_t = 10.0)]
    pub x_max: f64,
    /// Parameter box of the references: |r_i| <= r-max.
    #[arg(long, default_value_t = 3.0)]
    pub r_max: f64,
    /// The model is the tricopter's (4 pulse inputs motor 1-3 and servo, in
    /// us): the thesis PWM window around `u0` bounds the inputs and the
    /// throttle is the last parameter. Implied by inputs named
    /// `pwm1,pwm2,pwm3,servo`.
    #[arg(long, conflicts_with_all = ["u_min", "u_max"])]
    pub tricopter: bool,
    /// Smallest throttle of the parameter box (tricopter only, us; default 1000).
    #[arg(long)]
    pub throttle_min: Option<f64>,
    /// Largest throttle of the parameter box (tricopter only, us; default 2000).
    #[arg(long)]
    pub throttle_max: Option<f64>,
    /// Output file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

const AFTER_HELP: &str = "\
Input: a discrete-time model (kestrel.ss.v1 with ts > 0 and D = 0; u0/y0 optional), e.g. the
identified tricopter model models/tricopter-blackbox-5.json (inputs pwm1,pwm2,pwm3,servo in us,
outputs p,q,r in rad/s), plus the horizon, move blocking, weights and terminal cost below.
The tricopter (--tricopter, or a model whose inputs are named pwm1,pwm2,pwm3,servo): PWM
bounds around its u0 (motors 1000-2000 us minus the throttle, servo +-300 us) and the
throttle as the last parameter. Other models need --u-min/--u-max (deviations from u0) and
have no throttle parameter.

Output: the condensed parametric QP as kestrel.mpqp.v1 (--out, or standard output):
  min_z 1/2 z'Hz + theta'F z   s.t.   G z <= W + E theta,   theta_lb <= theta <= theta_ub,
with z = one input move per block (deviations from u0, us for the tricopter) and
theta = [x; r_1..r_ny; throttle] (tricopter: [x; r_roll; r_pitch; r_yaw; throttle]).
The explicit (kestrel empc) and fast-gradient (kestrel fgm) solvers read this file.

Examples:
  kestrel mpc --model models/tricopter-blackbox-5.json --horizon 2 --blocks 2 --q1 2000 --q2 0.01 --out thesis.json
  kestrel mpc --model models/tricopter-blackbox-5.json --horizon 10 --blocks 1,1,2,6 --q1 2000 --q2 0.01 --out larger.json";

/// A weight given on the command line: a number or a JSON matrix file.
pub fn parse_weight(text: &str, what: &str) -> anyhow::Result<Weight> {
    if let Ok(v) = text.trim().parse::<f64>() {
        if !v.is_finite() {
            bail!("{what}: expected a finite number or a JSON matrix file, found {text}");
        }
        return Ok(Weight::Scalar(v));
    }
    Ok(Weight::Matrix(read_matrix(Path::new(text), what)?))
}

/// Reads a JSON matrix file ([`matrix_from_text`]: an array of rows, or an
/// object holding it under the key `what`).
pub fn read_matrix(path: &Path, what: &str) -> anyhow::Result<DMatrix<f64>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{what}: reading {}", path.display()))?;
    matrix_from_text(&text, what, None, None).with_context(|| format!("{what}: {}", path.display()))
}

/// The problem described by the arguments.
pub fn build(args: &Args) -> anyhow::Result<MpcProblem> {
    let model = SsModel::read(&args.model).with_context(|| format!("{}", args.model.display()))?;
    let blocking = match &args.blocks {
        Some(b) => Some(Blocking::new(b.clone())?),
        None => None,
    };
    let terminal = match args.terminal.as_str() {
        "lq" => Terminal::Lq,
        "q1" => Terminal::StageWeight,
        path => {
            let m = read_matrix(Path::new(path), "--terminal")?;
            if m.shape() == (model.ny(), model.ny()) {
                Terminal::Output(Weight::Matrix(m))
            } else if m.shape() == (model.nx(), model.nx()) {
                Terminal::State(m)
            } else {
                bail!(
                    "--terminal {path}: expected a {ny} x {ny} output weight or a {nx} x {nx} state weight, found {} x {}",
                    m.nrows(),
                    m.ncols(),
                    ny = model.ny(),
                    nx = model.nx()
                );
            }
        }
    };
    let settings = MpcSettings {
        horizon: args.horizon,
        blocking,
        q1: parse_weight(&args.q1, "--q1")?,
        q2: parse_weight(&args.q2, "--q2")?,
        terminal,
        state_bound: args.x_max,
        reference_bound: args.r_max,
        ..MpcSettings::default()
    };
    let named_tricopter = model
        .inputs
        .as_ref()
        .is_some_and(|v| v.iter().map(String::as_str).eq(TRICOPTER_INPUTS));
    let tricopter = args.tricopter || (named_tricopter && args.u_min.is_none());
    if !tricopter {
        for (flag, given) in [
            ("--throttle-min", args.throttle_min.is_some()),
            ("--throttle-max", args.throttle_max.is_some()),
        ] {
            if given {
                bail!(
                    "{flag} applies to the tricopter (--tricopter) only; this problem has no throttle parameter"
                );
            }
        }
    }
    let settings = match (&args.u_min, &args.u_max) {
        (Some(lo), Some(hi)) => MpcSettings {
            input_bounds: Some(Bounds::new(
                DVector::from_column_slice(lo),
                DVector::from_column_slice(hi),
            )),
            ..settings
        },
        (None, None) if tricopter => {
            if model.nu() != 4 {
                bail!(
                    "--tricopter needs a model with the 4 pulse inputs motor 1-3 and servo, found {} inputs",
                    model.nu()
                );
            }
            let mut s = tricopter_trim(&model)
                .with_context(|| format!("{}: u0", args.model.display()))?
                .constrain(settings);
            let default = throttle_parameter();
            s.parameters = vec![kestrel_mpc::Parameter {
                min: args.throttle_min.unwrap_or(default.min),
                max: args.throttle_max.unwrap_or(default.max),
                ..default
            }];
            s
        }
        (None, None) => bail!(
            "the model's {} inputs ({}) are not the tricopter's pwm1, pwm2, pwm3, servo: give --u-min and --u-max (bounds as deviations from u0), or --tricopter for the thesis PWM window and throttle parameter",
            model.nu(),
            model
                .inputs
                .as_ref()
                .map_or_else(|| "unnamed".to_string(), |v| v.join(", "))
        ),
        _ => bail!("give both --u-min and --u-max, or neither"),
    };
    MpcProblem::build(&model, &settings)
        .map_err(|e| crate::guards::mpc(e, "--horizon"))
        .with_context(|| format!("building the MPC problem of {}", args.model.display()))
}

/// The input names of the tricopter's models (`kestrel identify`, `kestrel
/// simulate --rate-model`, models/tricopter-blackbox-5.json).
const TRICOPTER_INPUTS: [&str; 4] = ["pwm1", "pwm2", "pwm3", "servo"];

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let spinner = crate::progress::Spinner::new("condensing the MPC problem");
    let problem = build(&args)?;
    drop(spinner);
    // The model's fingerprint lets `kestrel export` check the problem's states.
    let model = SsModel::read(&args.model).with_context(|| format!("{}", args.model.display()))?;
    let text = problem.to_mpqp().to_json_string_for_model(&model);
    io::write_output(args.out.as_deref(), &text)
}
