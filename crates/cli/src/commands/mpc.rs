//! `kestrel mpc`: build the condensed MPC problem of a model and write it
//! as `kestrel.mpqp.v1`.

mod flags;

use crate::io;
use anyhow::{Context, bail};
use flags::{Entries, SOFT_DEFAULT};
use kestrel_core::formats::{SsModel, matrix_from_text};
use kestrel_mpc::{
    Blocking, Bounds, InputTarget, MpcError, MpcProblem, MpcSettings, Parameter, Terminal, Weight,
};
use kestrel_tricopter::{throttle_parameter, tricopter_trim};
use nalgebra::DMatrix;
use std::path::{Path, PathBuf};

/// Builds the condensed parametric QP (thesis (6.19)-(6.26), errata
/// applied, generalised: input-move weights and bounds, output and state
/// bounds, hard or soft, a reference preview, an input target, a terminal
/// set, parameter-dependent input bounds) of a discrete `kestrel.ss.v1`
/// model and writes it as `kestrel.mpqp.v1`. Without the new flags,
/// `theta = [x; r_1..r_ny; throttle]` (for the tricopter `[x; r_roll;
/// r_pitch; r_yaw; throttle]`); the after-help text gives the layout.
///
/// The tricopter (`--tricopter`, or a model whose inputs are named
/// `pwm1,pwm2,pwm3,servo`, said on standard error): its inputs are bounded
/// by the PWM ranges around its `u0` (motors within 1000-2000 us minus the
/// throttle, the servo within +-300 us of its centre) and the throttle is
/// the last parameter. Other models need `--u-min` and `--u-max`
/// (deviations from `u0`) and have no throttle parameter.
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
    /// Input weight Q2: a number (times the identity) or a JSON matrix file,
    /// on the input's deviation from its target (--u-target; default u0).
    #[arg(long, default_value = "1e-4", allow_negative_numbers = true)]
    pub q2: String,
    /// Terminal weight: `lq` (Riccati solution, thesis (7.18)-(7.19)),
    /// `q1` (Q1N = Q1), `none` (no terminal cost), or a JSON matrix file:
    /// ny x ny is the output weight Q1N, nx x nx (when nx != ny) the state
    /// weight on x_N - C^+ r.
    #[arg(long, default_value = "lq")]
    pub terminal: String,
    /// Lower input bounds, comma separated, as deviations from `u0`
    /// (required for models other than the tricopter's; not with
    /// `--tricopter`); `-inf` or an empty entry for none.
    #[arg(long, allow_hyphen_values = true, value_name = "A,B,..")]
    pub u_min: Option<String>,
    /// Upper input bounds, comma separated, as deviations from `u0`; `inf`
    /// or an empty entry for none.
    #[arg(long, allow_hyphen_values = true, value_name = "A,B,..")]
    pub u_max: Option<String>,
    /// Parameter box of the states written to the file: |x_i| <= x-max
    /// (a bound on theta, not a constraint on the predicted states: that
    /// is --state-min/--state-max).
    #[arg(long, default_value_t = 10.0)]
    pub x_max: f64,
    /// Parameter box of the references: |r_i| <= r-max.
    #[arg(long, default_value_t = 3.0)]
    pub r_max: f64,
    /// The model is the tricopter's (4 pulse inputs motor 1-3 and servo, in
    /// us): the thesis PWM window around `u0` bounds the inputs and the
    /// throttle is the last parameter. Implied by inputs named
    /// `pwm1,pwm2,pwm3,servo` (said on standard error; --u-min/--u-max
    /// avoid it).
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
    #[command(flatten)]
    pub replace: io::Replace,
    /// The general MPC flags (input moves, output and state bounds, soft
    /// bounds, preview, input target, terminal set, parameters); boxed to
    /// keep the command enum small.
    #[command(flatten)]
    pub general: Box<GeneralArgs>,
}

/// The flags of `kestrel mpc` beyond the thesis's problem: input-move
/// weight and bounds, output and state bounds (hard or soft), reference
/// preview, input target, terminal set, parameter-dependent input bounds.
#[derive(clap::Args, Debug)]
#[command(
    next_help_heading = "General MPC (input moves, output and state bounds, preview, target)"
)]
pub struct GeneralArgs {
    /// Weight on the input moves du_j = u_j - u_{j-1}: a number (times the
    /// identity) or a JSON matrix file (nu x nu). Puts the previous input
    /// u_prev in theta (u_{-1} = u_prev).
    #[arg(long, value_name = "W", allow_negative_numbers = true)]
    pub du_weight: Option<String>,
    /// Largest input move per step, comma separated, one per input (>= 0;
    /// `inf` or an empty entry for none). Puts u_prev in theta.
    #[arg(long, value_name = "A,B,..", allow_hyphen_values = true)]
    pub du_max: Option<String>,
    /// Largest move down per step (<= 0; default -du-max).
    #[arg(
        long,
        value_name = "A,B,..",
        allow_hyphen_values = true,
        requires = "du_max"
    )]
    pub du_min: Option<String>,
    /// Lower bounds on the predicted outputs y_j = C x_j (j = 1..N), one per
    /// output (`-inf` or an empty entry for none).
    #[arg(long, value_name = "A,B,..", allow_hyphen_values = true)]
    pub y_min: Option<String>,
    /// Upper bounds on the predicted outputs (`inf` or empty for none).
    #[arg(long, value_name = "A,B,..", allow_hyphen_values = true)]
    pub y_max: Option<String>,
    /// Lower bounds on the predicted states x_j (j = 1..N), one per state
    /// (`-inf` or an empty entry for none).
    #[arg(long, value_name = "A,B,..", allow_hyphen_values = true)]
    pub state_min: Option<String>,
    /// Upper bounds on the predicted states (`inf` or empty for none).
    #[arg(long, value_name = "A,B,..", allow_hyphen_values = true)]
    pub state_max: Option<String>,
    /// Makes bounds soft (a slack per bounded entry, penalised; the QP
    /// stays feasible): a comma separated list of `y` (output bounds), `x`
    /// (state bounds), `du` (input-move bounds); `--soft` alone is `y,x`.
    /// Input bounds stay hard.
    #[arg(long, value_name = "y,x,du", num_args = 0..=1, default_missing_value = SOFT_DEFAULT)]
    pub soft: Option<String>,
    /// Quadratic penalty of a slack, 1/2 Q s^2 (> 0; default 1e2).
    #[arg(
        long,
        value_name = "Q",
        requires = "soft",
        allow_negative_numbers = true
    )]
    pub soft_weight: Option<f64>,
    /// Linear (exact) penalty of a slack, L s (>= 0; default 1e4).
    #[arg(
        long,
        value_name = "L",
        requires = "soft",
        allow_negative_numbers = true
    )]
    pub soft_linear: Option<f64>,
    /// Reference steps in theta, 1..=N: y_j follows r_min(j, P) (1: a
    /// constant reference, the default).
    #[arg(long, value_name = "P", default_value_t = 1)]
    pub preview: usize,
    /// What Q2 pulls the inputs towards: comma separated numbers, one per
    /// input (deviations from u0), or `param` (an input target in theta).
    #[arg(long, value_name = "V,..|param", allow_hyphen_values = true)]
    pub u_target: Option<String>,
    /// Parameter box of the u_prev and u_target entries of theta whose
    /// input has no finite bound (--u-min/--u-max give the box otherwise):
    /// |u_i| <= u-param-max.
    #[arg(long, value_name = "B", default_value_t = MpcSettings::default().input_parameter_bound)]
    pub u_param_max: f64,
    /// A hard terminal set A x_N <= b: a JSON file {"a": rows (nx
    /// columns), "b": [..]}.
    #[arg(long, value_name = "FILE")]
    pub terminal_set: Option<PathBuf>,
    /// An extra parameter in theta, NAME=MIN:MAX (repeat for more; with
    /// --u-shift): the input bounds move with it.
    #[arg(long = "param", value_name = "NAME=MIN:MAX", requires = "u_shift")]
    pub params: Vec<String>,
    /// How the input bounds move with the --param parameters: a JSON
    /// matrix file, nu x (number of --param): both bounds of input i move
    /// by `shift[i][j]` per unit of parameter j.
    #[arg(long, value_name = "FILE", requires = "params", requires = "u_min")]
    pub u_shift: Option<PathBuf>,
}

const AFTER_HELP: &str = "\
Input: a discrete-time model (kestrel.ss.v1 with ts > 0 and D = 0; u0/y0 optional), e.g. the
identified tricopter model models/tricopter-blackbox-5.json (inputs pwm1,pwm2,pwm3,servo in us,
outputs p,q,r in rad/s), plus the horizon, move blocking, weights and terminal cost below.
The tricopter (--tricopter, or a model whose inputs are named pwm1,pwm2,pwm3,servo, said on
standard error): PWM bounds around its u0 (motors 1000-2000 us minus the throttle, servo
+-300 us) and the throttle as the last parameter. Other models need --u-min/--u-max
(deviations from u0) and have no throttle parameter. All bounds are in the model's
coordinates (inputs as deviations from u0, outputs y = C x); inf, -inf or an empty entry
is no bound.

Output: the condensed parametric QP as kestrel.mpqp.v1 (--out, or standard output):
  min_z 1/2 z'Hz + (F'theta + f)'z   s.t.   G z <= W + E theta,   theta_lb <= theta <= theta_ub,
with z = [one input move per block (deviations from u0, us for the tricopter); slacks (one
per softened bounded entry, --soft)].
Without the flags below, theta = [x; r_1..r_ny; throttle] (tricopter: [x; r_roll; r_pitch;
r_yaw; throttle]; other models have no throttle). In general, in this order:
  theta = [ x          nx        the state
            u_prev     nu        the previous input (with --du-weight, --du-max)
            r_1..r_P   ny each   the references of steps 1..P (P = --preview, default 1;
                                 y_j follows r_min(j,P), the terminal cost r_P)
            u_target   nu        the input target (with --u-target param)
            params     one each  --param in order; the tricopter's throttle ]
Rows of G: input upper, input lower (all blocks), move upper/lower, output, state, terminal
set, slacks >= 0. The explicit (kestrel empc) and fast-gradient (kestrel fgm) solvers read
this file.

Examples:
  kestrel mpc --model models/tricopter-blackbox-5.json --horizon 2 --blocks 2 --q1 2000 --q2 0.01 --out thesis.json
  kestrel mpc --model models/tricopter-blackbox-5.json --horizon 10 --blocks 1,1,2,6 --q1 2000 --q2 0.01 --out larger.json
A double integrator (inputs \"force\", no throttle):
  kestrel c2d --model examples/double-integrator.json --ts 0.1 --out di.json
  move weight and limit:   kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --du-weight 0.1 --du-max 0.2
  output limits, soft:     kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --y-min -0.5 --y-max 0.5 --soft --soft-weight 1e3 --soft-linear 1e4
  state limits (velocity): kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --state-min ,-2 --state-max ,2
  reference preview:       kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --preview 5
  no terminal cost:        kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --terminal none
  input target:            kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --u-target 0.2   (or --u-target param)
  terminal set:            kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --terminal-set set.json
                           (set.json: {\"a\": [[1, 0], [-1, 0]], \"b\": [0.1, 0.1]})
  bounds moving with a parameter: kestrel mpc --model di.json --horizon 10 --u-min -1 --u-max 1 --param load=0:1 --u-shift shift.json
                           (shift.json: [[-0.5]]: both input bounds move by -0.5 per unit of load)";

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
    let settings = settings(args, &model)?;
    MpcProblem::build(&model, &settings)
        .map_err(|e| match flag_of(&e) {
            Some(flag) => anyhow::Error::new(e).context(flag),
            None => crate::guards::mpc(e, "--horizon"),
        })
        .with_context(|| format!("building the MPC problem of {}", args.model.display()))
}

/// The flags behind a settings error of the library, when it names one.
fn flag_of(e: &MpcError) -> Option<&'static str> {
    let what = match e {
        MpcError::InvalidSetting { what, .. } | MpcError::Dimension { what, .. } => what,
        MpcError::NonFinite(what)
        | MpcError::NotSymmetric { what, .. }
        | MpcError::NotPositiveDefinite { what, .. } => what,
        // Other errors are not about one setting: passed on unchanged.
        _ => return None,
    };
    [
        ("input_bounds", "--u-min/--u-max"),
        ("du_bounds", "--du-min/--du-max"),
        ("du_weight", "--du-weight"),
        ("output_bounds", "--y-min/--y-max"),
        ("state_bounds", "--state-min/--state-max"),
        ("terminal_set", "--terminal-set"),
        ("preview", "--preview"),
        ("input_target", "--u-target"),
        ("input_parameter_bound", "--u-param-max"),
    ]
    .into_iter()
    .find(|(prefix, _)| what.starts_with(prefix))
    .map(|(_, flag)| flag)
}

/// The settings described by the arguments for `model`, every flag
/// checked (errors name the flag).
pub fn settings(args: &Args, model: &SsModel) -> anyhow::Result<MpcSettings> {
    let blocking = match &args.blocks {
        Some(b) => Some(Blocking::new(b.clone())?),
        None => None,
    };
    let inputs = Entries {
        what: "input",
        names: model.inputs.as_deref().unwrap_or(&[]),
        n: model.nu(),
    };
    let (input_bounds, parameters) = input_bounds(args, model, inputs)?;
    let mut s = MpcSettings {
        horizon: args.horizon,
        blocking,
        q1: parse_weight(&args.q1, "--q1")?,
        q2: parse_weight(&args.q2, "--q2")?,
        terminal: terminal(&args.terminal, model)?,
        state_bound: args.x_max,
        reference_bound: args.r_max,
        du_weight: args
            .general
            .du_weight
            .as_deref()
            .map(|w| parse_weight(w, "--du-weight"))
            .transpose()?,
        preview: flags::preview(args.general.preview, args.horizon)?,
        input_target: match &args.general.u_target {
            Some(t) => flags::input_target(t, inputs)?,
            None => InputTarget::Zero,
        },
        input_bounds: Some(input_bounds),
        terminal_set: args
            .general
            .terminal_set
            .as_deref()
            .map(|p| flags::terminal_set(p, model.nx()))
            .transpose()?,
        parameters,
        input_parameter_bound: args.general.u_param_max,
        ..MpcSettings::default()
    };
    state_and_output_bounds(args, model, inputs, &mut s)?;
    Ok(s)
}

/// The terminal cost of `--terminal`.
fn terminal(text: &str, model: &SsModel) -> anyhow::Result<Terminal> {
    Ok(match text {
        "lq" => Terminal::Lq,
        "q1" => Terminal::StageWeight,
        "none" => Terminal::None,
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
    })
}

/// The move, output and state bounds (`--du-*`, `--y-*`, `--state-*`),
/// soft as `--soft` says.
fn state_and_output_bounds(
    args: &Args,
    model: &SsModel,
    inputs: Entries<'_>,
    s: &mut MpcSettings,
) -> anyhow::Result<()> {
    let outputs = Entries {
        what: "output",
        names: model.outputs.as_deref().unwrap_or(&[]),
        n: model.ny(),
    };
    let states = Entries {
        what: "state",
        names: &[],
        n: model.nx(),
    };
    let pair = |(lower, upper)| Bounds::new(lower, upper);
    s.du_bounds = match &args.general.du_max {
        Some(max) => Some(pair(flags::move_bounds(
            max,
            args.general.du_min.as_deref(),
            inputs,
        )?)),
        None => None,
    };
    s.output_bounds = flags::bound_pair(
        args.general.y_min.as_deref(),
        args.general.y_max.as_deref(),
        ("--y-min", "--y-max"),
        outputs,
    )?
    .map(pair);
    s.state_bounds = flags::bound_pair(
        args.general.state_min.as_deref(),
        args.general.state_max.as_deref(),
        ("--state-min", "--state-max"),
        states,
    )?
    .map(pair);
    let Some(list) = &args.general.soft else {
        return Ok(());
    };
    let families = flags::soft_families(list)?;
    let penalty = flags::soft_penalty(args.general.soft_weight, args.general.soft_linear)?;
    let mut softened = false;
    for (wanted, bounds) in [
        (families.outputs, &mut s.output_bounds),
        (families.states, &mut s.state_bounds),
        (families.moves, &mut s.du_bounds),
    ] {
        if let (true, Some(b)) = (wanted, bounds.as_mut()) {
            b.soft = Some(penalty);
            softened = true;
        }
    }
    if !softened {
        bail!(
            "--soft {list}: there are no such bounds to soften; give --y-min/--y-max (y), --state-min/--state-max (x) or --du-max (du)"
        );
    }
    Ok(())
}

/// The input bounds and the extra parameters: the tricopter's PWM window
/// and throttle, or `--u-min/--u-max` moved by `--param`/`--u-shift`.
fn input_bounds(
    args: &Args,
    model: &SsModel,
    inputs: Entries<'_>,
) -> anyhow::Result<(Bounds, Vec<Parameter>)> {
    let named_tricopter = super::tricopter_names::has_tricopter_inputs(model);
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
    match (&args.u_min, &args.u_max) {
        (Some(lo), Some(hi)) => {
            let (lower, upper) =
                flags::bound_pair(Some(lo), Some(hi), ("--u-min", "--u-max"), inputs)?
                    .expect("both given");
            let bounds = Bounds::new(lower, upper);
            let parameters = args
                .general
                .params
                .iter()
                .map(|p| flags::parameter(p))
                .collect::<anyhow::Result<Vec<_>>>()?;
            for (i, p) in parameters.iter().enumerate() {
                if parameters[..i].iter().any(|q| q.name == p.name) {
                    bail!("--param {}: the name is given twice", p.name);
                }
            }
            let Some(path) = &args.general.u_shift else {
                return Ok((bounds, parameters));
            };
            let shift = read_matrix(path, "--u-shift")?;
            if shift.shape() != (model.nu(), parameters.len()) {
                bail!(
                    "--u-shift {}: expected a {} x {} matrix (one row per input, one column per --param), found {} x {}",
                    path.display(),
                    model.nu(),
                    parameters.len(),
                    shift.nrows(),
                    shift.ncols()
                );
            }
            if let Some(i) = (0..model.nu()).find(|&i| {
                shift.row(i).amax() > 0.0
                    && !(bounds.lower[i].is_finite() && bounds.upper[i].is_finite())
            }) {
                bail!(
                    "--u-shift {}: row {} moves {}, whose --u-min/--u-max has an infinite side; a shift moves finite bounds only",
                    path.display(),
                    i + 1,
                    inputs.label(i)
                );
            }
            Ok((bounds.shifted(shift), parameters))
        }
        (None, None) if tricopter => {
            if model.nu() != 4 {
                bail!(
                    "--tricopter needs a model with the 4 pulse inputs motor 1-3 and servo, found {} inputs",
                    model.nu()
                );
            }
            if !args.tricopter {
                eprintln!(
                    "note: the model's inputs are named pwm1, pwm2, pwm3, servo, so this is the tricopter's problem (the thesis PWM window around u0, the throttle as the last parameter); give --u-min and --u-max for plain input bounds and no throttle"
                );
            }
            tricopter_bounds(args, model)
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
    }
}

/// The thesis's PWM window and throttle parameter for a tricopter model.
fn tricopter_bounds(args: &Args, model: &SsModel) -> anyhow::Result<(Bounds, Vec<Parameter>)> {
    let trim = tricopter_trim(model).with_context(|| format!("{}: u0", args.model.display()))?;
    let default = throttle_parameter();
    let throttle = Parameter {
        min: args.throttle_min.unwrap_or(default.min),
        max: args.throttle_max.unwrap_or(default.max),
        ..default
    };
    Ok((trim.bounds(), vec![throttle]))
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace.check(&[args.out.as_deref()])?;
    let spinner = crate::progress::Spinner::new("condensing the MPC problem");
    let problem = build(&args)?;
    drop(spinner);
    // The model's fingerprint lets `kestrel export` check the problem's states.
    let model = SsModel::read(&args.model).with_context(|| format!("{}", args.model.display()))?;
    let text = problem.to_mpqp().to_json_string_for_model(&model);
    io::write_output(args.out.as_deref(), &text)
}
