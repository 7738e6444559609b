//! `kestrel simulate`: fly one of the thesis's experiments in the tricopter
//! simulator and write the 50 Hz CSV flight log.

use crate::io;
use anyhow::Context;
use kestrel_tricopter_model::{Experiment, RateInputs, RateModelKind, SimSettings};
use std::path::PathBuf;

/// Flies experiment 1-4 of the thesis (hover, decoupled or coupled
/// excitation, motors off on the ground) with the baseline ACRO rate
/// controller and a simulated pilot, and writes the CSV log (columns in the
/// kestrel-tricopter-model README). The same seed gives the same file.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Experiment: hover, decoupled, coupled or ground.
    #[arg(long)]
    pub experiment: Experiment,
    /// Length of the log in seconds (take-off at 2 s, landing in the last
    /// 3.5 s); at most 10,000 s (500,000 rows, about 300 MB of CSV).
    #[arg(long, default_value_t = 250.0, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Random seed (gyro noise, gusts, excitation).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// RK4 integration step in seconds (must divide the 20 ms sample
    /// period); seconds / dt at most 1e8 steps (a minute or two).
    #[arg(long, default_value_t = 1e-3, allow_negative_numbers = true)]
    pub dt: f64,
    /// No gyro bias, noise, quantisation or gusts.
    #[arg(long)]
    pub noiseless: bool,
    /// Also write the true reduced rate model (rates + actuators, PWM
    /// inputs), discretised at 50 Hz, as `kestrel.ss.v1` to this file.
    #[arg(long)]
    pub rate_model: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace
        .check(&[args.out.as_deref(), args.rate_model.as_deref()])?;
    let mut settings = SimSettings::new(args.experiment, args.seconds, args.seed);
    settings.plant.dt = args.dt;
    if args.noiseless {
        settings = settings.noiseless();
    }
    let _spinner = crate::progress::Spinner::new(&format!(
        "flying experiment {} ({} s)",
        args.experiment.name(),
        args.seconds
    ));
    let log = kestrel_tricopter_model::simulate(&settings)
        .map_err(crate::guards::simulation)
        .with_context(|| format!("simulating experiment {}", args.experiment.name()))?;
    let bytes = log.to_csv_bytes()?;
    let text = String::from_utf8(bytes).context("CSV log is not UTF-8")?;
    // Every output is computed, then all are written together.
    let mut outputs = io::Outputs::new();
    if let Some(path) = &args.rate_model {
        let model = kestrel_tricopter_model::rate_model_discrete(
            &settings.plant.params,
            RateModelKind::WithActuators,
            RateInputs::Pwm,
            1.0 / settings.plant.gyro.rate_hz,
        )?;
        outputs.add(Some(path), model.to_json_string())?;
    }
    outputs.add(args.out.as_deref(), text)?;
    outputs.commit()?;
    eprintln!("{}: {}", args.experiment.name(), log.trim);
    if args.experiment != Experiment::Ground && !log.rows.iter().any(|r| r.airborne) {
        eprintln!(
            "note: the aircraft never left the ground in these {} s (take-off at 2 s, landing in the last 3.5 s): the log has no airborne sample; fly 6 s or more",
            args.seconds
        );
    }
    Ok(())
}
