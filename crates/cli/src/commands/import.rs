//! `kestrel import`: a flight log (Betaflight blackbox, Crazyflie uSD,
//! PX4 ULog) to kestrel's CSV on one uniform grid.

use crate::io;
use anyhow::{Context, bail};
use kestrel_logs::{
    AirborneSettings, ImportSettings, Imported, LogError, ReadOptions, SegmentChoice, SignalSpec,
};
use std::path::PathBuf;

/// Which part of the log to write.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentArg {
    /// The airborne segments (motor level above --threshold), each an experiment.
    Airborne,
    /// The whole log.
    All,
}

/// Reads a flight log (format recognised from its first bytes), resamples
/// the chosen signals onto one uniform grid by cell means (never by picking
/// samples), keeps the airborne segments, and writes kestrel's CSV: a `t`
/// column (seconds, cell centres), one column per signal and, with several
/// segments or logs, an `experiment` column. Gyro rates in rad/s; motor
/// commands raw (see docs/logs.md for units and axes per format).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The log: Betaflight `.bbl`/`.bfl` (every log in the file), Crazyflie
    /// uSD binary, or PX4 `.ulg`.
    pub log: PathBuf,
    /// Grid rate in Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate: f64,
    /// Input signals, comma-separated `name=source` or field names
    /// (default per format: Betaflight motor0..3 = motor[0..3], Crazyflie
    /// m1..m4 = motor.m1..4, PX4 motorK = `actuator_motors.control[K]`).
    #[arg(long)]
    pub inputs: Option<String>,
    /// Output signals (default p,q,r: Betaflight gyroADC[0..2], Crazyflie
    /// gyro.x/y/z, PX4 vehicle_angular_velocity.xyz), in rad/s.
    #[arg(long)]
    pub outputs: Option<String>,
    /// Airborne segments or the whole log.
    #[arg(long, value_enum, default_value_t = SegmentArg::Airborne)]
    pub segment: SegmentArg,
    /// Airborne above this mean motor level, as a fraction of the
    /// command range (0 = its low end, 1 = full).
    #[arg(long, default_value_t = AirborneSettings::default().threshold)]
    pub threshold: f64,
    /// Shortest airborne segment kept, seconds.
    #[arg(long, default_value_t = AirborneSettings::default().min_duration_s)]
    pub min_duration: f64,
    /// Seconds cut from both ends of each airborne segment.
    #[arg(long, default_value_t = AirborneSettings::default().trim_s)]
    pub trim: f64,
    /// A longer stretch without samples (seconds) splits an experiment.
    #[arg(long, default_value_t = 0.1)]
    pub max_gap: f64,
    /// Keep what can be read from a damaged log (each problem reported
    /// with its byte offset) instead of failing at the first.
    #[arg(long)]
    pub salvage: bool,
    /// List the log's topics and fields (names to pick with --inputs and
    /// --outputs, units, ranges, sample counts and rates) instead of
    /// importing.
    #[arg(long)]
    pub list: bool,
    /// Output CSV file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace.check(&[args.out.as_deref()])?;
    if args.list {
        let logs = kestrel_logs::read_file(
            &args.log,
            &ReadOptions {
                salvage: args.salvage,
            },
        )
        .with_context(|| format!("{}", args.log.display()))?;
        return io::write_output(None, &listing(&logs));
    }
    let spec = |flag: &str, s: &Option<String>| -> anyhow::Result<Option<Vec<SignalSpec>>> {
        s.as_deref()
            .map(SignalSpec::parse_list)
            .transpose()
            .with_context(|| flag.to_string())
    };
    let settings = ImportSettings {
        rate_hz: args.rate,
        inputs: spec("--inputs", &args.inputs)?,
        outputs: spec("--outputs", &args.outputs)?,
        segment: match args.segment {
            SegmentArg::Airborne => SegmentChoice::Airborne,
            SegmentArg::All => SegmentChoice::All,
        },
        airborne: AirborneSettings {
            threshold: args.threshold,
            min_duration_s: args.min_duration,
            trim_s: args.trim,
            ..AirborneSettings::default()
        },
        max_gap_s: args.max_gap,
        read: ReadOptions {
            salvage: args.salvage,
        },
    };
    let imported = match kestrel_logs::import_file(&args.log, &settings) {
        Ok(imported) => imported,
        Err(e @ (LogError::Corrupt { .. } | LogError::Truncated { .. })) if !args.salvage => {
            bail!(
                "{}: {e}; --salvage keeps what can be read",
                args.log.display()
            )
        }
        Err(e) => return Err(anyhow::Error::new(e).context(format!("{}", args.log.display()))),
    };
    eprint!("{}", summary(&imported));
    io::write_output(args.out.as_deref(), &imported.to_csv())
}

/// The topics and fields of every log, for `--list`.
fn listing(logs: &[kestrel_logs::Log]) -> String {
    use std::fmt::Write as _;
    const FACTS: [&str; 6] = [
        "Firmware revision",
        "Craft name",
        "Board information",
        "looptime",
        "P interval",
        "motorOutput",
    ];
    let mut s = String::new();
    for (k, log) in logs.iter().enumerate() {
        let _ = writeln!(s, "log {}: {} at byte {}", k + 1, log.format, log.offset);
        for (key, value) in log
            .info
            .iter()
            .filter(|(key, _)| FACTS.contains(&key.as_str()))
        {
            let _ = writeln!(s, "  {key}: {value}");
        }
        for i in &log.issues {
            let _ = writeln!(s, "  warning: {i}");
        }
        for t in &log.topics {
            let n = t.t.len();
            let (a, b) = (
                t.t.first().copied().unwrap_or(0.0),
                t.t.last().copied().unwrap_or(0.0),
            );
            let rate = if b > a { (n - 1) as f64 / (b - a) } else { 0.0 };
            let _ = writeln!(
                s,
                "  topic {}: {n} samples, {a:.3}-{b:.3} s, {rate:.1} Hz",
                t.name
            );
            for f in &t.fields {
                let range = f
                    .range
                    .map_or(String::new(), |[lo, hi]| format!(", range {lo}..{hi}"));
                let _ = writeln!(s, "    {}.{} [{}{range}]", t.name, f.name, f.unit);
            }
        }
    }
    s
}

/// What was imported, for standard error.
fn summary(imp: &Imported) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "{} log, {} Hz grid, signals:", imp.format, imp.rate_hz);
    for (k, sig) in imp.signals.iter().enumerate() {
        let role = if k < imp.n_inputs { "input " } else { "output" };
        let range = sig
            .range
            .map_or(String::new(), |[a, b]| format!(", range {a}..{b}"));
        let _ = writeln!(
            s,
            "  {role} {:<8} = {} [{}{range}]",
            sig.name, sig.source, sig.unit
        );
    }
    for (k, l) in imp.logs.iter().enumerate() {
        let segs: Vec<String> = l
            .segments
            .iter()
            .map(|g| format!("{:.2}-{:.2} s", g.start, g.end))
            .collect();
        let _ = writeln!(
            s,
            "log {}: {} samples at {:.1} Hz over {:.2}-{:.2} s; segments: {}; gaps split: {}",
            k + 1,
            l.samples,
            l.native_rate_hz,
            l.span.start,
            l.span.end,
            if segs.is_empty() {
                "none".into()
            } else {
                segs.join(", ")
            },
            l.gaps.len()
        );
        for i in &l.issues {
            let _ = writeln!(s, "  warning: {i}");
        }
    }
    let filled: usize = imp.experiments.iter().map(|e| e.filled).sum();
    let _ = writeln!(
        s,
        "{} experiment(s), {} rows; {} empty cell(s) interpolated",
        imp.experiments.len(),
        imp.n_samples(),
        filled
    );
    s
}
