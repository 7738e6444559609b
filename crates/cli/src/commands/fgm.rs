//! `kestrel fgm certify|solve`: the certified fast gradient method.

use super::problem_thetas::ProblemThetas;
use super::scalar_arg::ScalarArg;
use crate::io;
use anyhow::{Context, bail};
use kestrel_core::formats::MpqpProblem;
use kestrel_fgm::{
    AppliedInputs, BoxQp, ExportScalar, FgmDesign, FgmSettings, Momentum, Preconditioner, Start,
    WarmStartAssumption, export_rust,
};
use nalgebra::DVector;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// Fast gradient method for `kestrel.mpqp.v1` problems with box constraints.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub command: FgmCommand,
}

/// The `fgm` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum FgmCommand {
    /// Certify the iteration count for `J - J* <= eps` over the parameter box.
    ///
    /// Input: a `kestrel.mpqp.v1` problem (`--problem`) whose constraint rows
    /// each bound one variable (any order and scaling; bounds affine in
    /// theta), and the tolerance `--eps` on `J(z) - J*`.
    ///
    /// Output (JSON, `kestrel.fgm.certificate.v1`, to stdout or `--out`):
    /// `iterations` (certified, after the initial projected gradient step,
    /// for a cold start at the box centre), `L`, `mu`, `condition` of the
    /// scaled Hessian, `preconditioner` with `before`/`after` spectra,
    /// `delta` (and Richter's `delta_richter`), `eps_table` (eps 1e5, 1e4,
    /// 1e3, 1e2 and the input-error eps, each with its certified
    /// iterations), `input_tolerance` (the eps that keeps the applied inputs
    /// within `--input-error` of the optimum, computed from diag(H^-1), and
    /// its iterations), `pwm_1us` (the same for an error of 1 problem unit,
    /// 1 us for the tricopter's pulse widths), `rounding`
    /// (f32 and Q16 error bounds) and, with `--theta-step`, `warm` (the
    /// warm-start certificate). `linear_bound` (null if mu = 0) and
    /// `sublinear_bound` are null when beyond 2^53 iterations (with a
    /// `bound_note`); an eps that no bound reaches is an error. `--export`
    /// also writes the firmware tables.
    Certify(CertifyArgs),
    /// Solve for each theta of a CSV file with a fixed iteration count.
    ///
    /// Input: the problem (`--problem`, as for `certify`), a CSV file of
    /// parameters (`--thetas`: one theta per row, p numbers, no header) and
    /// `--iterations` (after the initial projected gradient step; take
    /// `iterations` from `certify` for a certified accuracy). Every solve is
    /// a cold start from the box centre, in f64.
    ///
    /// Output (CSV, to stdout or `--out`): one row per theta, the n entries
    /// of z in the problem's units, no header. Parameters outside the
    /// problem's box (`theta_lb`, `theta_ub`) are solved too, with a warning
    /// on standard error: the certificate does not cover them.
    Solve(SolveArgs),
}

/// Preconditioner choice on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum PreconditionerArg {
    /// D = I.
    None,
    /// D = diag(H)^-1/2.
    Jacobi,
    /// The diagonal minimising cond(D H D) (an SDP solved with clarabel).
    OptimalDiagonal,
}

impl From<PreconditionerArg> for Preconditioner {
    fn from(p: PreconditionerArg) -> Self {
        match p {
            PreconditionerArg::None => Preconditioner::None,
            PreconditionerArg::Jacobi => Preconditioner::Jacobi,
            PreconditionerArg::OptimalDiagonal => Preconditioner::OptimalDiagonal,
        }
    }
}

/// Momentum choice on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum MomentumArg {
    /// The scheme with the smaller certified count.
    Auto,
    /// Constant beta (needs mu > 0).
    Constant,
    /// Precomputed beta table.
    Table,
}

/// Flags of `kestrel fgm certify`.
#[derive(clap::Args, Debug)]
pub struct CertifyArgs {
    /// Problem file (`kestrel.mpqp.v1`, every constraint row bounding one variable).
    #[arg(long)]
    pub problem: PathBuf,
    /// Tolerance on J(z) - J* (positive).
    #[arg(long, allow_negative_numbers = true)]
    pub eps: f64,
    /// Diagonal preconditioner.
    #[arg(long, value_enum, default_value = "optimal-diagonal")]
    pub preconditioner: PreconditionerArg,
    /// Momentum scheme.
    #[arg(long, value_enum, default_value = "auto")]
    pub momentum: MomentumArg,
    /// Warm start: largest change of each parameter between two solves,
    /// comma separated (p numbers); adds a warm-start certificate.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub theta_step: Option<Vec<f64>>,
    /// How many leading variables are the applied inputs (the first move)
    /// for the input tolerance (`input_tolerance`, `pwm_1us`); default: all
    /// variables.
    #[arg(long)]
    pub applied_inputs: Option<usize>,
    /// The largest error of an applied input the `input_tolerance` eps
    /// allows, in the problem's units (positive; 1 is 1 us for the
    /// tricopter's pulse widths).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub input_error: f64,
    /// Write the firmware tables as a Rust `static` to this file.
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// Scalar type of the exported tables.
    #[arg(long, value_enum, default_value = "f32")]
    pub scalar: ScalarArg,
    /// Output file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// Flags of `kestrel fgm solve`.
#[derive(clap::Args, Debug)]
pub struct SolveArgs {
    #[command(flatten)]
    pub input: ProblemThetas,
    /// Fast-gradient iterations after the initial projected gradient step
    /// (at most 1,000,000, and 1e12 operations over all parameters; `certify`
    /// gives the count for a tolerance).
    #[arg(long)]
    pub iterations: usize,
    /// Diagonal preconditioner.
    #[arg(long, value_enum, default_value = "optimal-diagonal")]
    pub preconditioner: PreconditionerArg,
    /// Output file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        FgmCommand::Certify(a) => certify(a),
        FgmCommand::Solve(a) => solve(a),
    }
}

fn load(path: &Path, pc: PreconditionerArg, momentum: Momentum) -> anyhow::Result<FgmDesign> {
    let name = path.display().to_string();
    let prob = MpqpProblem::read(path).with_context(|| name.clone())?;
    let qp = BoxQp::from_mpqp(&prob).with_context(|| name.clone())?;
    let settings = FgmSettings {
        preconditioner: pc.into(),
        momentum,
        ..FgmSettings::default()
    };
    let _spinner = crate::progress::Spinner::new("preconditioning and certifying");
    FgmDesign::new(qp, settings).with_context(|| name)
}

fn certify(a: CertifyArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.out.as_deref(), a.export.as_deref()])?;
    if !(a.eps.is_finite() && a.eps > 0.0) {
        bail!("--eps must be a positive finite number, got {}", a.eps);
    }
    let momentum = match a.momentum {
        MomentumArg::Auto => Momentum::Auto,
        MomentumArg::Constant => Momentum::Constant,
        MomentumArg::Table => Momentum::Table,
    };
    if let Some(step) = &a.theta_step
        && let Some((j, v)) = step
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
    {
        bail!(
            "--theta-step: entry {} is {v}; each entry is the largest change of one parameter between two solves, a number >= 0",
            j + 1
        );
    }
    if !(a.input_error.is_finite() && a.input_error > 0.0) {
        bail!(
            "--input-error {}: the largest error of an applied input must be a positive number (in the problem's units)",
            a.input_error
        );
    }
    let d = load(&a.problem, a.preconditioner, momentum)?;
    if let Some(k) = a.applied_inputs.filter(|&k| k == 0 || k > d.n()) {
        bail!(
            "--applied-inputs {k}: the problem has {} variables; the applied inputs are the first 1 to {} of them",
            d.n(),
            d.n()
        );
    }
    let cert = d.certify(a.eps)?;
    // The count holds in exact arithmetic; a tolerance below the rounding
    // of the cost itself (relative to the initial gap delta) is one no
    // floating-point solve reaches, so say so rather than let the count
    // read as attainable.
    let floor = d.delta() * f64::EPSILON;
    if a.eps < floor {
        eprintln!(
            "note: --eps {:e} is below f64's rounding of this problem's cost (initial gap {:e} x 2^-52 = {floor:.1e}); the {} iterations are certified in exact arithmetic, an f64 (or f32) solve does not reach that accuracy",
            a.eps,
            d.delta(),
            cert.iterations
        );
    }
    let pc = &d.preconditioning;
    let applied = match a.applied_inputs {
        Some(k) => AppliedInputs::FirstMove(k),
        None => AppliedInputs::All,
    };
    let mut table: Vec<Value> = d
        .certify_table(&[1e5, 1e4, 1e3, 1e2])?
        .iter()
        .map(|c| json!({"eps": c.eps, "iterations": c.iterations}))
        .collect();
    // The eps for an input error of one unit (`pwm_1us`, kept as it was)
    // and for `--input-error` (`input_tolerance`), each in the table.
    let mut tolerance = |error: f64| -> anyhow::Result<Value> {
        Ok(match d.input_tolerance(error, applied) {
            Ok(t) => {
                let c = d.certify(t.eps)?;
                let mut row =
                    json!({"eps": t.eps, "iterations": c.iterations, "input_error": error});
                if error == 1.0 {
                    row["pwm_error"] = json!(1.0);
                }
                table.push(row);
                json!({"max_input_error": error, "eps": t.eps, "iterations": c.iterations,
                       "applied_inputs": a.applied_inputs.unwrap_or(d.n()),
                       "worst_variable": t.worst_variable, "h_inv_diag": t.h_inv_diag,
                       "eps_eigenvalue": t.eps_eigenvalue})
            }
            Err(e) => json!({"max_input_error": error, "eps": null, "note": e.to_string()}),
        })
    };
    let pwm = tolerance(1.0)?;
    let input = if a.input_error == 1.0 {
        pwm.clone()
    } else {
        tolerance(a.input_error)?
    };
    let rounding = |b: Option<kestrel_fgm::RoundingBound>| match b {
        Some(b) => json!({"cost_bound": b.cost_bound, "distance_bound": b.distance_bound,
                          "gradient_error": b.gradient_error, "box_shrink": b.box_shrink}),
        None => Value::Null,
    };
    let mut out = json!({
        "format": "kestrel.fgm.certificate.v1",
        "problem": a.problem.display().to_string(),
        "n": d.n(),
        "p": d.problem.p(),
        "eps": cert.eps,
        "iterations": cert.iterations,
        "L": cert.l,
        "mu": cert.mu,
        "condition": cert.condition,
        "delta": cert.delta,
        "delta_richter": cert.delta_richter,
        "cold_start": "box centre",
        "diameter_sq": cert.diameter_sq,
        "linear_bound": cert.linear_bound,
        "sublinear_bound": cert.sublinear_bound,
        "momentum": cert.scheme.name(),
        "preconditioner": pc.method.name(),
        "before": {"L": pc.before.l, "mu": pc.before.mu, "condition": pc.before.condition()},
        // L and mu of D H D with the scaling actually used (D is also
        // normalised so the scaled iterates use the range of fixed point).
        "after": {"L": cert.l, "mu": cert.mu, "condition": cert.condition},
        "eps_table": table,
        "input_tolerance": input,
        "pwm_1us": pwm,
        "rounding": {
            "f32": rounding(d.rounding_bound::<f32>(&cert)),
            "q16": rounding(d.rounding_bound::<kestrel_core::Q16>(&cert)),
        },
    });
    if cert.sublinear_bound.is_none() || (cert.linear_bound.is_none() && cert.mu > 0.0) {
        out["bound_note"] = json!(format!(
            "a null linear_bound or sublinear_bound exceeds {} iterations (eps is far below what that rate can certify); iterations uses the other bound",
            kestrel_fgm::MAX_ITERATION_BOUND
        ));
    }
    let mut warm_iterations = None;
    if let Some(step) = &a.theta_step {
        let assume = WarmStartAssumption {
            prev_eps: a.eps,
            theta_step: DVector::from_column_slice(step),
        };
        let w = d.certify_warm(a.eps, &assume)?;
        warm_iterations = Some(w.iterations);
        out["warm"] = json!({"iterations": w.iterations, "refined": w.refined,
                             "radius": w.radius, "delta": w.delta,
                             "recommended_start": w.recommended().name(),
                             "recommended_iterations": w.recommended_iterations()});
    }
    // Both outputs are staged, then written together.
    let mut outputs = io::Outputs::new();
    if let Some(path) = &a.export {
        // The firmware table holds one momentum per iteration.
        let most = cert.iterations.max(warm_iterations.unwrap_or(0));
        if most > crate::guards::MAX_FGM_ITERATIONS {
            bail!(
                "--export: the certified {most} iterations exceed the firmware tables' limit of {} (one momentum per iteration, and the time budget); certify a larger --eps",
                crate::guards::MAX_FGM_ITERATIONS
            );
        }
        let scalar = ExportScalar::from(a.scalar);
        let text = match a.scalar {
            ScalarArg::F32 => export_rust("FGM", &d.data::<f32>(&cert, warm_iterations)?, scalar)?,
            ScalarArg::F64 => export_rust("FGM", &d.data::<f64>(&cert, warm_iterations)?, scalar)?,
            ScalarArg::Q16 => export_rust(
                "FGM",
                &d.data::<kestrel_core::Q16>(&cert, warm_iterations)?,
                scalar,
            )?,
        };
        outputs.add(Some(path), text)?;
        out["export"] = json!({"path": path.display().to_string(), "scalar": a.scalar.name()});
    }
    let text = serde_json::to_string_pretty(&out)? + "\n";
    outputs.add(a.out.as_deref(), text)?;
    outputs.commit()
}

fn solve(a: SolveArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.out.as_deref()])?;
    let d = load(&a.input.problem, a.preconditioner, Momentum::Auto)?;
    let numbered = a.input.read_thetas(d.problem.p(), d.problem.n())?;
    let (thetas, lines) = (&numbered.rows, &numbered.lines);
    let outside: Vec<(usize, usize)> = thetas
        .iter()
        .enumerate()
        .filter_map(|(k, th)| d.problem.outside_parameter_box(th).map(|j| (k, j)))
        .collect();
    if let Some(&(k, j)) = outside.first() {
        let qp = &d.problem;
        eprintln!(
            "warning: {} of {} parameters lie outside the problem's parameter box, which the certificate covers (first: {} line {}, entry {} = {:?} not in [{:?}, {:?}]); they are solved anyway, without a certified accuracy",
            outside.len(),
            thetas.len(),
            a.input.thetas.display(),
            lines[k],
            j + 1,
            thetas[k][j],
            qp.theta_lb[j],
            qp.theta_ub[j]
        );
    }
    // Any eps gives the same scaled data; the momentum scheme follows the
    // certificate's choice for a tight tolerance.
    crate::guards::fgm_iterations(a.iterations, d.problem.n(), thetas.len())?;
    let cert = d.certify(1e-9 * d.delta().max(f64::MIN_POSITIVE))?;
    let data = d.data::<f64>(&cert, Some(a.iterations))?;
    let mut out = String::new();
    for (k, th) in thetas.iter().enumerate() {
        let z = data
            .solve(th, Start::Cold, a.iterations)
            .with_context(|| format!("{}: line {}", a.input.thetas.display(), lines[k]))?;
        let cells: Vec<String> = z.iter().map(|v| format!("{v:?}")).collect();
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    io::write_output(a.out.as_deref(), &out)
}
