//! `kestrel export`: the example firmware's controller tables from design files.

mod c_files;

use crate::io;
use anyhow::{Context, anyhow, bail};
use kestrel_core::formats::SsModel;
use kestrel_fgm::Preconditioner;
use kestrel_kalman::KalmanDesign;
use kestrel_tricopter::ProblemSize;
use kestrel_tricopter::firmware::{
    DesignError, DesignPart, DesignSettings, FirmwareDesign, IterationBudget, ProblemCheck,
    ProblemFile, QpTables, Realization, c_tables, generate_qp_tables, generate_qp16_tables,
    generate_tables,
};
use std::path::PathBuf;

/// Writes the firmware tables (`avr/firmware/src/generated.rs`, Rust source)
/// from design files.
///
/// In: the 50 Hz design model (`kestrel.ss.v1`, 4 inputs pwm1, pwm2, pwm3,
/// servo in us with the hover trim as `u0`; 3 outputs p, q, r in rad/s);
/// optionally the stationary Kalman filter (`kestrel.kalman.v1`, from
/// `kestrel kalman`; default: kestrel-tricopter's noise design with the thesis's
/// gyro covariance and bias) and the condensed MPC problem
/// (`kestrel.mpqp.v1`, from `kestrel mpc`, parameters `[x; p_ref, q_ref,
/// r_ref; throttle]`; default: the tricopter problem of `--size`).
/// The files must belong together, not only fit in size: the filter's
/// model (its `ts`, `A`, `B`, `C`, `D`, `u0`) must be the design model, or
/// the design model with constant disturbance states (the offset-free
/// estimator `kestrel pipeline` writes as `kalman.json`), and the problem
/// must be built on the filter's model (its `model_fingerprint`, written
/// by `kestrel mpc` and `kestrel pipeline`; a problem without one is
/// checked by size only, with a warning).
/// The fast gradient method is preconditioned and certified for the
/// iteration count that keeps every input within `--max-input-error` us of
/// the optimum.
///
/// Out: Rust source with the dimensions, the iteration counts, the offset
/// of each part and the flat table (Kalman A, B, C, M, y0; fast-gradient
/// data; mixer trim; gyro bias) in f32 and in Q15.16 raw bits. With
/// `--lang c`, the same tables as C in the folder `--out`:
/// `kestrel_design.h` (sizes, offsets and the design checksums as macros,
/// declarations) and `kestrel_design.c` (`const` tables, `PROGMEM` on the
/// AVR, and kestrel-ffi's `KestrelDesign` for them), with `--empc` also
/// the explicit law's table (`kestrel_empc.h`, `kestrel_empc.c`); files
/// there that `kestrel export --lang c` did not write are never replaced.
/// With `--qp-out FILE` (Rust), also the problem as the box QP tables of
/// the firmware's `qp` build (`generated_qp.rs`), with `--qp16-out FILE`
/// as the fixed-point tables of its `qp16` build (`generated_qp16.rs`),
/// all written together.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Design model (`kestrel.ss.v1`, discrete, 4 inputs, 3 outputs).
    #[arg(long)]
    pub model: PathBuf,
    /// Stationary Kalman filter (`kestrel.kalman.v1`) of the same model.
    #[arg(long)]
    pub kalman: Option<PathBuf>,
    /// Condensed MPC problem (`kestrel.mpqp.v1`) of the same model.
    #[arg(long)]
    pub problem: Option<PathBuf>,
    /// Problem built when `--problem` is not given.
    #[arg(long, value_enum, default_value_t = Size::Thesis)]
    pub size: Size,
    /// Largest error (us) of any input against the exact optimum; sets the
    /// fast gradient's certified iteration count.
    #[arg(long, default_value_t = 1.0)]
    pub max_input_error: f64,
    /// Preconditioner of the fast gradient method.
    #[arg(long, value_enum, default_value_t = Precond::OptimalDiagonal)]
    pub preconditioner: Precond,
    /// Run this many warm-started iterations per period instead of the
    /// certified cold-start count (not certified).
    #[arg(long)]
    pub warm_iterations: Option<usize>,
    /// State coordinates when the filter and problem are designed here
    /// (neither `--kalman` nor `--problem`): `schur` (real Schur form, the
    /// Kalman step skips the zeros of the quasi-triangular A) or `as-given`.
    #[arg(long, value_enum, default_value_t = Coordinates::Schur)]
    pub realization: Coordinates,
    /// Output: with `--lang rust`, the file for the Rust source of the
    /// firmware tables (default: standard output); with `--lang c`, the
    /// folder for `kestrel_design.h` and `kestrel_design.c` (created if
    /// missing; required).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
    /// Language of the tables: `rust` (the firmware's `generated.rs`) or
    /// `c` (`kestrel_design.h` and `kestrel_design.c` for C and C++
    /// firmware with kestrel-ffi).
    #[arg(long, value_enum, default_value_t = Lang::Rust)]
    pub lang: Lang,
    /// With `--lang c`: also the explicit law of the MPC problem
    /// (kestrel-empc's exact solution as the firmware's 16-bit search
    /// tree) as `kestrel_empc.h` and `kestrel_empc.c`.
    #[arg(long)]
    pub empc: bool,
    /// With `--lang rust`: also write the same MPC problem as the box QP
    /// tables of the firmware's `qp` build (kestrel-qp's exact dual
    /// active-set solver; `avr/firmware/src/generated_qp.rs`) to this
    /// file, written together with `--out`.
    #[arg(long, value_name = "FILE")]
    pub qp_out: Option<PathBuf>,
    /// With `--lang rust`: also write the same problem as the fixed-point
    /// tables of the firmware's `qp16` build (kestrel-avr-rt's Q15.16
    /// active-set solver; `avr/firmware/src/generated_qp16.rs`) to this
    /// file, written together with `--out`.
    #[arg(long, value_name = "FILE")]
    pub qp16_out: Option<PathBuf>,
}

/// `--lang`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lang {
    /// Rust source (`avr/firmware/src/generated.rs`).
    Rust,
    /// A C header and source.
    C,
}

/// `--realization`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Coordinates {
    /// Real Schur form.
    Schur,
    /// The model's own.
    AsGiven,
}

/// `--size`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Size {
    /// N = 2, Ns = 1 (the thesis's).
    Thesis,
    /// N = 10, blocks [1, 1, 2, 6].
    Larger,
}

/// `--preconditioner`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Precond {
    /// No scaling.
    None,
    /// Unit diagonal.
    Jacobi,
    /// The condition-minimising diagonal (SDP).
    OptimalDiagonal,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    // With --lang c, --out is a folder whose files are replaced only when
    // this command wrote them (`c_files`).
    if args.lang == Lang::Rust {
        args.replace.check(&[
            args.out.as_deref(),
            args.qp_out.as_deref(),
            args.qp16_out.as_deref(),
        ])?;
    }
    for (flag, given) in [
        ("--qp-out", args.qp_out.is_some()),
        ("--qp16-out", args.qp16_out.is_some()),
    ] {
        if given && args.lang != Lang::Rust {
            bail!(
                "{flag} writes the Rust firmware's QP tables: it goes with --lang rust (the C tables carry the fast gradient's data)"
            );
        }
    }
    if let (Lang::C, None) = (args.lang, &args.out) {
        bail!(
            "--lang c writes two files ({} and {}): give the folder for them with --out DIR",
            c_tables::C_HEADER_NAME,
            c_tables::C_SOURCE_NAME
        );
    }
    if args.empc && args.lang != Lang::C {
        bail!(
            "--empc writes C tables: add --lang c (the firmware's Rust explicit tables are written by `kestrel codegen`)"
        );
    }
    let model = SsModel::read(&args.model).with_context(|| format!("{}", args.model.display()))?;
    if model.ts <= 0.0 {
        bail!(
            "{}: the model is continuous-time (ts = {}); discretise it first with `kestrel c2d`",
            args.model.display(),
            model.ts
        );
    }
    super::tricopter_names::note_if_not_the_tricopter(&model, &args.model, "the example firmware");
    let settings = DesignSettings {
        max_input_error_us: args.max_input_error,
        preconditioner: match args.preconditioner {
            Precond::None => Preconditioner::None,
            Precond::Jacobi => Preconditioner::Jacobi,
            Precond::OptimalDiagonal => Preconditioner::OptimalDiagonal,
        },
        size: match args.size {
            Size::Thesis => ProblemSize::Thesis,
            Size::Larger => ProblemSize::Larger,
        },
        budget: match args.warm_iterations {
            Some(k) => IterationBudget::WarmFixed(k),
            None => IterationBudget::Certified,
        },
        realization: match args.realization {
            Coordinates::Schur => Realization::Schur,
            Coordinates::AsGiven => Realization::AsGiven,
        },
    };
    let design = match (&args.kalman, &args.problem) {
        (None, None) => FirmwareDesign::from_model(&model, &settings)?,
        (kalman, problem) => {
            let kalman = match kalman {
                Some(p) => Some(KalmanDesign::read(p).with_context(|| format!("{}", p.display()))?),
                None => None,
            };
            let problem = match problem {
                Some(p) => Some(ProblemFile::read(p).with_context(|| format!("{}", p.display()))?),
                None => None,
            };
            let (design, checked) = FirmwareDesign::from_parts(&model, kalman, problem, &settings)
                .map_err(|e| name_parts(e, &args))?;
            if let (ProblemCheck::SizesOnly, Some(p)) = (checked.problem, &args.problem) {
                eprintln!(
                    "warning: {} has no model_fingerprint (older files lack it; `kestrel mpc` and `kestrel pipeline` write it): only its sizes are checked against the filter's model; rebuild it to have it checked",
                    p.display()
                );
            }
            design
        }
    };
    match (args.lang, &args.out) {
        (Lang::C, Some(dir)) => {
            let c = c_tables::generate_c_tables(&design)?;
            let mut files = vec![
                (c_tables::C_HEADER_NAME, c.header.as_str()),
                (c_tables::C_SOURCE_NAME, c.source.as_str()),
            ];
            let e = match args.empc {
                true => Some(c_tables::generate_c_empc_of(&design)?),
                false => None,
            };
            if let Some(e) = &e {
                files.push((c_tables::empc::C_EMPC_HEADER_NAME, e.header.as_str()));
                files.push((c_tables::empc::C_EMPC_SOURCE_NAME, e.source.as_str()));
            }
            c_files::write(dir, &files)?;
            let names: Vec<&str> = files.iter().map(|(n, _)| *n).collect();
            eprintln!(
                "export: wrote {} in {} (design checksums f32 0x{:04X}, Q15.16 0x{:04X}{})",
                names.join(", "),
                dir.display(),
                c.checksum_f32,
                c.checksum_q16,
                e.map(|e| format!(", explicit law 0x{:04X}", e.checksum))
                    .unwrap_or_default()
            );
        }
        (Lang::C, None) | (Lang::Rust, _) => {
            let source = generate_tables(&design)?;
            let mut outputs = io::Outputs::new();
            outputs.add(args.out.as_deref(), &source)?;
            if let Some(path) = &args.qp_out {
                outputs.add(Some(path), generate_qp_tables(&design)?)?;
            }
            if let Some(path) = &args.qp16_out {
                let tables = generate_qp16_tables(&design).context(
                    "--qp16-out: the qp16 build's fixed-point solver is sized for the thesis's problem",
                )?;
                outputs.add(Some(path), tables)?;
            }
            outputs.commit()?;
            if let Some(path) = &args.qp16_out {
                eprintln!(
                    "export: wrote the qp16 build's fixed-point tables to {}",
                    path.display()
                );
            }
            if let Some(path) = &args.qp_out {
                let t = QpTables::of(&design);
                let values = t.values().count();
                // f32 values and workspace; usize is 2 bytes on the AVR.
                let ram = 4 * (values + kestrel_qp::scalar_len(t.n, 0))
                    + 2 * kestrel_qp::index_len(t.n, 0);
                eprintln!(
                    "export: wrote the qp build's tables to {} ({} variables, {} parameters; {values} f32 values, with the solver's workspace about {ram} bytes of the ATmega2560's 8 kB RAM)",
                    path.display(),
                    t.n,
                    t.p
                );
            }
        }
    }
    eprintln!(
        "export: {} states, {} variables, {} parameters; fast gradient eps {:.3e}, condition {:.3}, {} certified iterations, {} per period",
        design.nx(),
        design.data_f64.n,
        design.data_f64.p,
        design.eps,
        design.cert.condition,
        design.cert.iterations,
        design.loop_iterations()
    );
    Ok(())
}

/// A mismatch between two design files, named by their paths (or as the
/// default built here); other errors unchanged.
fn name_parts(e: DesignError, args: &Args) -> anyhow::Error {
    let model = args.model.display();
    let name = |part: DesignPart| match part {
        DesignPart::Model => format!("--model {model}"),
        DesignPart::Kalman => match &args.kalman {
            Some(p) => format!("--kalman {}", p.display()),
            None => format!(
                "the default Kalman filter (designed here for {model}; give --kalman for another)"
            ),
        },
        DesignPart::Problem => match &args.problem {
            Some(p) => format!("--problem {}", p.display()),
            None => format!(
                "the default MPC problem (built here on {model}; give --problem for another)"
            ),
        },
    };
    match e {
        DesignError::Mismatch {
            first,
            second,
            detail,
        } => {
            let hint = match (first, second) {
                (DesignPart::Kalman, _) => format!(
                    "give the model the filter was designed for, or design one for {model} with `kestrel kalman --model {model}`"
                ),
                (DesignPart::Problem, _) => format!(
                    "give the files the problem was built with, or build it on {model} with `kestrel mpc --model {model} --tricopter --horizon N`"
                ),
                (DesignPart::Model, _) => "give design files of one model".to_string(),
            };
            anyhow!(
                "{} and {} do not belong together: {detail}; {hint}",
                name(first),
                name(second)
            )
        }
        other => other.into(),
    }
}
