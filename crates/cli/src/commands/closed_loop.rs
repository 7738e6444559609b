//! `kestrel closed-loop`: fly a rate controller in the closed-loop
//! simulator (thesis section 7.7) and write the trace as CSV.

use crate::io;
use anyhow::{Context, bail};
use kestrel_core::formats::SsModel;
use kestrel_fgm::{FgmOptions, FgmStart};
use kestrel_mpc::{
    Blocking, DisturbanceModel, MpcLaw, MpcProblem, MpcSettings, ParametricQpSolver, QpSettings,
    Terminal,
};
use kestrel_tricopter::closed_loop::{
    PlantKind as SimPlant, RunResult, RunSettings, fly_mpc, fly_offset_free, fly_pi, kalman_design,
    kalman_design_with_disturbance,
};
use kestrel_tricopter::{ProblemSize, default_weights, identified_model, tricopter_trim};
use std::path::PathBuf;

/// The controller flown.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Controller {
    /// MPC with the clarabel reference QP solve at every step.
    Qp,
    /// Explicit MPC (kestrel-empc): the mpQP solved once, point location per step.
    Empc,
    /// Fast-gradient MPC (kestrel-fgm) with a fixed iteration count (`--iterations`).
    Fgm,
    /// MPC with the exact dual active-set solver (kestrel-qp) at every step, cold or (`--start warm`) from the previous step's active set.
    ActiveSet,
    /// The baseline PI rate controller (ArduCopter ACRO-like) on the raw gyro.
    Pid,
}

/// The plant flown.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlantKind {
    /// The nonlinear tricopter (RK4 at 1 kHz, gusts when noisy).
    Nonlinear,
    /// The design model itself (linear), with the gyro.
    Linear,
}

/// Problem size presets.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Size {
    /// N = 2, one block of two steps (the thesis's Ns = 1).
    Thesis,
    /// N = 10, blocks 1,1,2,6.
    Larger,
}

/// Where each fast-gradient or active-set solve starts.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Start {
    /// From the centre of the input box (the certified start; fgm), from the empty active set (active-set).
    Cold,
    /// From the previous step's solution (fgm) or final active set (active-set).
    Warm,
    /// From the previous solution shifted by one move (fgm only).
    Shifted,
}

const AFTER_HELP: &str = "\
Inputs: a design model (kestrel.ss.v1 with 4 pulse inputs pwm1,pwm2,pwm3,servo in us and 3 rate
outputs p,q,r in rad/s, operating point u0/y0; default: the built-in identified 5-state model,
models/tricopter-blackbox-5.json, embedded at build time; a feed-through D is moved one sample
later, as it acts in the loop) and the MPC settings below. The MPC
controllers run the stationary Kalman filter designed from the model (kestrel-kalman dlqe) and
the condensed QP with the tricopter's PWM bounds around u0 (motors 1000-2000 us, servo +-300 us).

Scenario (thesis 7.7.1): released at body rates [2, 2, 2] rad/s with zero reference, a step to
[1, -1, 0.5] rad/s at t = 2 s, 4 s in all, 50 Hz, hover throttle.

Output: the CSV trace (--out, or standard output), one row per sample with columns
t, r_p, r_q, r_r, throttle, p, q, r (true rates), p_meas, q_meas, r_meas (gyro),
p_est, q_est, r_est (Kalman estimate), pwm1, pwm2, pwm3, servo (pulses sent, us),
saturated (1 if any pulse was clipped), J (the MPC cost (6.3a) of the law's move sequence,
empty for pid). A summary goes to standard error: rise time, overshoot, RMS tracking error,
actuator effort (RMS pulse from trim) per axis, the largest bound violation; rise time is
from the step until the rate first crosses 90 % of the step, \"not reached\" when it never does.
A run whose rates leave max(3 x the largest released rate or reference, 5 rad/s) diverged:
an error, no trace written.

Examples:
  kestrel closed-loop --controller qp --out qp.csv
  kestrel closed-loop --controller fgm --iterations 5 --start warm --noise --out fgm5.csv
  kestrel closed-loop --controller active-set --start warm --size larger --out as.csv
  kestrel closed-loop --controller empc --model my-model.json --size thesis --out empc.csv";

/// Flies the scenario of thesis 7.7.1 with the chosen controller and
/// writes the trace (see `kestrel closed-loop --help`).
#[derive(clap::Args, Debug)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// The controller.
    #[arg(long, value_enum)]
    pub controller: Controller,
    /// Design model (`kestrel.ss.v1`, 4 pulse inputs, 3 rate outputs);
    /// default: the built-in identified 5-state model
    /// (models/tricopter-blackbox-5.json).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Problem size; `--horizon`/`--blocks` override it.
    #[arg(long, value_enum, default_value = "thesis")]
    pub size: Size,
    /// Prediction horizon N (overrides `--size`; one block per step unless
    /// `--blocks`); at most 1000 decision variables (blocks x 4 inputs).
    #[arg(long)]
    pub horizon: Option<usize>,
    /// Move-blocking lengths, comma separated, summing to N (overrides `--size`).
    #[arg(long, value_delimiter = ',')]
    pub blocks: Option<Vec<usize>>,
    /// Output weight Q1: a number (times the identity) or a JSON matrix file (default 2000).
    #[arg(long)]
    pub q1: Option<String>,
    /// Input weight Q2: a number (times the identity) or a JSON matrix file (default 0.01).
    #[arg(long)]
    pub q2: Option<String>,
    /// Fast-gradient iterations per step (`--controller fgm` only; default
    /// 12; at most 1,000,000, and 1e12 operations over the flight).
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Where each solve starts (`--controller fgm` and `active-set` only;
    /// default `cold`; `shifted` for fgm only).
    #[arg(long, value_enum)]
    pub start: Option<Start>,
    /// Offset-free MPC: constant torque disturbances on the rate states,
    /// estimated by the Kalman filter (not with `pid`).
    #[arg(long)]
    pub offset_free: bool,
    /// The plant.
    #[arg(long, value_enum, default_value = "nonlinear")]
    pub plant: PlantKind,
    /// Gyro noise and bias (7.5)-(7.6) and gusts, as in figures 7.18-7.21.
    #[arg(long)]
    pub noise: bool,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

fn settings(args: &Args) -> anyhow::Result<MpcSettings> {
    let size = match args.size {
        Size::Thesis => ProblemSize::Thesis,
        Size::Larger => ProblemSize::Larger,
    };
    let (dq1, dq2) = default_weights();
    let q1 = match &args.q1 {
        Some(t) => super::mpc::parse_weight(t, "--q1")?,
        None => dq1,
    };
    let q2 = match &args.q2 {
        Some(t) => super::mpc::parse_weight(t, "--q2")?,
        None => dq2,
    };
    let mut s = size.settings(q1, q2);
    if let Some(n) = args.horizon {
        s.horizon = n;
        s.blocking = None;
    }
    if let Some(b) = &args.blocks {
        s.blocking = Some(Blocking::new(b.clone())?);
    }
    s.terminal = Terminal::Lq;
    Ok(s)
}

/// Flies `problem`'s law with `solver` (plain or offset-free).
fn fly_law<S: ParametricQpSolver>(
    model: &SsModel,
    design: &Design,
    solver: S,
    run: &RunSettings,
) -> anyhow::Result<(RunResult, S)> {
    let mut law = MpcLaw::new(design.problem(), solver)?;
    let result = match design {
        Design::Plain(problem) => fly_mpc(model, problem, &mut law, &kalman_design(model)?, run)?,
        Design::OffsetFree(d) => {
            let kalman = kalman_design_with_disturbance(&d.augmented, d.nd)?;
            fly_offset_free(d, &mut law, &kalman, run)?
        }
    };
    Ok((result, law.into_solver()))
}

enum Design {
    Plain(Box<MpcProblem>),
    OffsetFree(Box<kestrel_mpc::OffsetFreeDesign>),
}

impl Design {
    fn problem(&self) -> &MpcProblem {
        match self {
            Design::Plain(p) => p,
            Design::OffsetFree(d) => &d.problem,
        }
    }
}

/// The controller's name as on the command line.
fn controller_name(c: Controller) -> &'static str {
    match c {
        Controller::Qp => "qp",
        Controller::Empc => "empc",
        Controller::Fgm => "fgm",
        Controller::ActiveSet => "active-set",
        Controller::Pid => "pid",
    }
}

fn fly(args: &Args, model: &SsModel, run: &RunSettings) -> anyhow::Result<RunResult> {
    if args.controller != Controller::Fgm {
        let start_applies = args.controller == Controller::ActiveSet;
        for (flag, given, users) in [
            ("--iterations", args.iterations.is_some(), "fgm"),
            (
                "--start",
                args.start.is_some() && !start_applies,
                "fgm and active-set",
            ),
        ] {
            if given {
                bail!(
                    "{flag} applies to --controller {users} only; --controller {} does not use it",
                    controller_name(args.controller)
                );
            }
        }
    }
    if args.controller == Controller::Pid {
        for (flag, given) in [
            ("--offset-free", args.offset_free),
            ("--horizon", args.horizon.is_some()),
            ("--blocks", args.blocks.is_some()),
            ("--q1", args.q1.is_some()),
            ("--q2", args.q2.is_some()),
        ] {
            if given {
                bail!("{flag} applies to the MPC controllers, not to pid");
            }
        }
        return Ok(fly_pi(model, run)?);
    }
    let trim = tricopter_trim(model)?;
    let s = settings(args)?;
    let design = if args.offset_free {
        Design::OffsetFree(Box::new(
            MpcProblem::build_offset_free(
                model,
                &trim.constrain(s.clone()),
                &DisturbanceModel::OutputStates,
            )
            .map_err(|e| crate::guards::mpc(e, "--horizon"))
            .context("building the offset-free MPC problem")?,
        ))
    } else {
        Design::Plain(Box::new(
            MpcProblem::build(model, &trim.constrain(s.clone()))
                .map_err(|e| crate::guards::mpc(e, "--horizon"))
                .context("building the MPC problem")?,
        ))
    };
    let mpqp = design.problem().to_mpqp();
    match args.controller {
        Controller::Qp => {
            let solver = kestrel_mpc::ReferenceSolver::new(&mpqp, QpSettings::default())?;
            Ok(fly_law(model, &design, solver, run)?.0)
        }
        Controller::Empc => {
            eprintln!(
                "solving the mpQP explicitly (n = {}, p = {}, {} constraints) ...",
                mpqp.n(),
                mpqp.p(),
                mpqp.m()
            );
            crate::guards::announce_explicit(
                mpqp.n(),
                mpqp.m(),
                "--controller fgm or qp fly the same problem without it, and --size thesis is the small problem",
            );
            let solver = kestrel_empc::ExplicitSolver::build(
                &mpqp,
                &kestrel_empc::Settings {
                    parallel: true,
                    progress: crate::progress::enabled(),
                    ..kestrel_empc::Settings::default()
                },
            )?;
            eprintln!("explicit MPC: {} critical regions", solver.regions());
            let (result, solver) = fly_law(model, &design, solver, run)?;
            if solver.outside() > 0 {
                eprintln!(
                    "explicit MPC: {} of {} steps had theta outside the explored set (clamped law of the nearest region)",
                    solver.outside(),
                    result.trace.rows.len()
                );
            }
            Ok(result)
        }
        Controller::Fgm => {
            let iterations = args.iterations.unwrap_or(12);
            if iterations == 0 {
                bail!("--iterations: expected at least 1");
            }
            crate::guards::fgm_iterations(iterations, mpqp.n(), 200)?;
            let opts = FgmOptions {
                iterations,
                start: match args.start.unwrap_or(Start::Cold) {
                    Start::Cold => FgmStart::Cold,
                    Start::Warm => FgmStart::Warm,
                    Start::Shifted => FgmStart::WarmShifted,
                },
                ..FgmOptions::default()
            };
            let solver = kestrel_fgm::FastGradientSolver::for_problem(design.problem(), &opts)?;
            Ok(fly_law(model, &design, solver, run)?.0)
        }
        Controller::ActiveSet => {
            let start = match args.start {
                Some(Start::Warm) => kestrel_qp::Start::Warm,
                Some(Start::Cold) | None => kestrel_qp::Start::Cold,
                Some(Start::Shifted) => bail!(
                    "--start shifted applies to --controller fgm only; the active-set solver starts cold or warm"
                ),
            };
            let solver =
                kestrel_qp::ActiveSetSolver::new(&mpqp, kestrel_qp::QpSettings::default(), start)?;
            let (result, solver) = fly_law(model, &design, solver, run)?;
            eprintln!(
                "active-set: {} solves, at most {} active-set changes per step",
                solver.solves(),
                solver.worst_iterations()
            );
            Ok(result)
        }
        Controller::Pid => unreachable!("handled above"),
    }
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace.check(&[args.out.as_deref()])?;
    let model = match &args.model {
        Some(p) => {
            let m = SsModel::read(p).with_context(|| format!("{}", p.display()))?;
            // Refused before any note on how its channels would be read.
            if m.nu() != 4 || m.ny() != 3 {
                bail!(
                    "{}: the closed loop flies the tricopter simulator, so the design model must have 4 pulse inputs and 3 rate outputs (motors 1-3 and the tail servo; p, q, r), found {} inputs and {} outputs; for another plant, build its problem with `kestrel mpc` and solve it with `kestrel qp solve`, `kestrel fgm solve` or `kestrel empc solve`",
                    p.display(),
                    m.nu(),
                    m.ny()
                );
            }
            super::tricopter_names::note_if_not_the_tricopter(&m, p, "the closed loop");
            m
        }
        None => identified_model()?,
    };
    // A feed-through D acts one sample later in the loop (kestrel_tricopter::delay_feedthrough).
    let model = if model.d.iter().any(|v| *v != 0.0) {
        let m = kestrel_tricopter::delay_feedthrough(&model)?;
        eprintln!(
            "the model has a feed-through D: designing on its strictly proper form with D acting one sample later ({} states)",
            m.nx()
        );
        m
    } else {
        model
    };
    let mut run = if args.noise {
        RunSettings::noisy()
    } else {
        RunSettings::default()
    };
    run.seed = args.seed;
    run.plant = match args.plant {
        PlantKind::Nonlinear => SimPlant::Nonlinear,
        PlantKind::Linear => SimPlant::Linear,
    };
    // The explicit solve shows a bar of its own.
    let spinner = (args.controller != Controller::Empc).then(|| {
        crate::progress::Spinner::new(&format!(
            "flying --controller {}",
            controller_name(args.controller)
        ))
    });
    let result = fly(&args, &model, &run)?;
    drop(spinner);
    let m = &result.metrics;
    if let Some(d) = &m.diverged {
        bail!(
            "--controller {}: the closed loop diverged (lost control): {d}; the step figures would mean nothing and no trace is written (check the model: its inputs, outputs and units, and a feed-through D)",
            controller_name(args.controller)
        );
    }
    let f = |v: &[f64]| {
        v.iter()
            .map(|x| {
                if x.is_finite() {
                    format!("{x:.3}")
                } else {
                    "not reached".to_string()
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    eprintln!(
        "{}: rise time (from the step to 90 %) [{}] s, overshoot [{}] %, RMS error [{}] rad/s, effort (RMS pulse from trim) [{}] us, largest bound violation {:.3} us",
        controller_name(args.controller),
        f(&m.rise_time),
        f(&m.overshoot),
        f(&m.rms_error),
        f(&m.effort),
        m.max_bound_violation
    );
    io::write_output(args.out.as_deref(), &result.trace.to_csv())
}
