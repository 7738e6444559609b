//! `kestrel closed-loop`: fly a rate controller in the closed-loop
//! simulator (thesis section 7.7) and write the trace as CSV.

use crate::io;
use anyhow::{Context, bail};
use kestrel_core::formats::SsModel;
use kestrel_mpc::sim::{
    LinearPlant, NonlinearPlant, RatePlant, Scenario, Trace, kalman_design, run_mpc, run_pid,
};
use kestrel_mpc::{
    Blocking, MpcLaw, MpcProblem, MpcSettings, ProblemSize, QpSettings, Terminal, default_weights,
    design_model, tricopter_trim,
};
use kestrel_tricopter_model::{GustConfig, GyroConfig, Mixer, PlantConfig, RatePid, RatePidGains};
use std::path::PathBuf;

/// The controller flown.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Controller {
    /// MPC with the clarabel reference QP solve at every step.
    Qp,
    /// Explicit MPC (kestrel-empc).
    Empc,
    /// Fast-gradient MPC (kestrel-fgm).
    Fgm,
    /// The baseline PI rate controller (ArduCopter ACRO-like).
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

/// Flies the scenario of thesis 7.7.1 (released at rates [2, 2, 2] rad/s,
/// then a step to [1, -1, 0.5] rad/s) and writes the trace: `t`, the
/// references, throttle, true/measured/estimated rates, the four pulses,
/// a clipping flag and the MPC's cost `J` of each step. A summary (rise
/// time, overshoot, RMS tracking error, actuator effort per axis) goes to
/// standard error.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The controller.
    #[arg(long, value_enum)]
    pub controller: Controller,
    /// Design model (`kestrel.ss.v1`, 4 pulse inputs, 3 rate outputs);
    /// default: the rates-plus-actuators linearisation of the default
    /// aircraft at 50 Hz.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Problem size: `thesis` (N = 2, one block) or `larger` (N = 10,
    /// blocks 1,1,2,6); `--horizon`/`--blocks` override it.
    #[arg(long, default_value = "thesis")]
    pub size: String,
    /// Prediction horizon N (overrides `--size`).
    #[arg(long)]
    pub horizon: Option<usize>,
    /// Move-blocking lengths, comma separated (overrides `--size`).
    #[arg(long, value_delimiter = ',')]
    pub blocks: Option<Vec<usize>>,
    /// Output weight Q1: a number (times the identity) or a JSON matrix file.
    #[arg(long)]
    pub q1: Option<String>,
    /// Input weight Q2: a number (times the identity) or a JSON matrix file.
    #[arg(long)]
    pub q2: Option<String>,
    /// The plant.
    #[arg(long, value_enum, default_value = "nonlinear")]
    pub plant: PlantKind,
    /// Gyro noise (7.5)-(7.6) and gusts, as in figures 7.18-7.21.
    #[arg(long)]
    pub noise: bool,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

macro_rules! with_filter {
    ($nx:expr, $design:expr, |$f:ident| $body:expr) => {
        match $nx {
            1 => {
                let mut $f = $design.filter::<f64, 1, 4, 3>()?;
                $body
            }
            2 => {
                let mut $f = $design.filter::<f64, 2, 4, 3>()?;
                $body
            }
            3 => {
                let mut $f = $design.filter::<f64, 3, 4, 3>()?;
                $body
            }
            4 => {
                let mut $f = $design.filter::<f64, 4, 4, 3>()?;
                $body
            }
            5 => {
                let mut $f = $design.filter::<f64, 5, 4, 3>()?;
                $body
            }
            6 => {
                let mut $f = $design.filter::<f64, 6, 4, 3>()?;
                $body
            }
            7 => {
                let mut $f = $design.filter::<f64, 7, 4, 3>()?;
                $body
            }
            8 => {
                let mut $f = $design.filter::<f64, 8, 4, 3>()?;
                $body
            }
            9 => {
                let mut $f = $design.filter::<f64, 9, 4, 3>()?;
                $body
            }
            10 => {
                let mut $f = $design.filter::<f64, 10, 4, 3>()?;
                $body
            }
            n => bail!("closed-loop supports design models with 1 to 10 states, found {n}"),
        }
    };
}

fn settings(args: &Args) -> anyhow::Result<MpcSettings> {
    let size = match args.size.as_str() {
        "thesis" => ProblemSize::Thesis,
        "larger" => ProblemSize::Larger,
        other => bail!("--size: expected thesis or larger, found {other}"),
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

fn fly<P: RatePlant>(args: &Args, model: &SsModel, plant: &mut P) -> anyhow::Result<Trace> {
    let scenario = Scenario::thesis_step();
    let trim = tricopter_trim(model)?;
    match args.controller {
        Controller::Pid => {
            let o = trim.offsets;
            let mut pid = RatePid::new(
                RatePidGains::default(),
                Mixer::new([o[0], o[1], o[2], 1500.0 + o[3]]),
            );
            Ok(run_pid(plant, &mut pid, &trim, &scenario, model.ts)?)
        }
        Controller::Empc | Controller::Fgm => bail!(
            "--controller {:?}: not available yet; the {} law plugs into the simulator through kestrel_mpc::ParametricQpSolver once its crate implements it",
            args.controller,
            if args.controller == Controller::Empc {
                "explicit-MPC"
            } else {
                "fast-gradient"
            }
        ),
        Controller::Qp => {
            let problem = MpcProblem::build(model, &trim.bounds(), &settings(args)?)
                .context("building the MPC problem")?;
            let mut law = MpcLaw::clarabel(&problem, QpSettings::default())?;
            let design = kalman_design(model)?;
            with_filter!(model.nx(), design, |f| Ok(run_mpc(
                plant,
                &mut law,
                &mut f,
                model,
                &problem,
                &scenario,
                |l| Some(l.last_z().to_vec())
            )?))
        }
    }
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = match &args.model {
        Some(p) => SsModel::read(p).with_context(|| format!("{}", p.display()))?,
        None => design_model()?,
    };
    if model.nu() != 4 || model.ny() != 3 {
        bail!(
            "the design model must have 4 pulse inputs and 3 rate outputs, found {} inputs and {} outputs",
            model.nu(),
            model.ny()
        );
    }
    let scenario = Scenario::thesis_step();
    let mut config = PlantConfig::default();
    if !args.noise {
        config.gyro = GyroConfig::ideal();
        config.gust = GustConfig::calm();
    }
    let trace = match args.plant {
        PlantKind::Nonlinear => {
            let mut p = NonlinearPlant::hovering(config, scenario.initial_rates, args.seed)?;
            fly(&args, &model, &mut p)?
        }
        PlantKind::Linear => {
            let mut p = LinearPlant::new(&model, scenario.initial_rates, config.gyro, args.seed)?;
            fly(&args, &model, &mut p)?
        }
    };
    let step = &scenario.steps[0];
    let m = trace.step_metrics(step.time, scenario.initial_reference, step.rates);
    let f = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    eprintln!(
        "{:?}: rise time [{}] s, overshoot [{}] %, RMS error [{}] rad/s, effort (RMS pulse from trim) [{}] us, largest bound violation {:.3} us",
        args.controller,
        f(&m.rise_time),
        f(&m.overshoot),
        f(&m.rms_error),
        f(&m.effort),
        m.max_bound_violation
    );
    io::write_output(args.out.as_deref(), &trace.to_csv())
}
