//! `kestrel qp`: kestrel-qp's dual active-set solver at given parameters
//! (`solve`) and its complexity certificate (`certify`).

use super::problem_thetas::ProblemThetas;
use crate::{io, progress};
use anyhow::Context;
use kestrel_core::formats::{MpqpProblem, NumberedRows};
use kestrel_empc::certify::{Certificate, CertifySettings, Count, QpSettings, certify};
use kestrel_qp::parametric::ParametricQp;
use kestrel_qp::{QpError, QpScalar, Start};
use serde_json::json;
use std::path::PathBuf;
use std::time::Duration;

/// The online dual active-set QP solver (kestrel-qp).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub command: QpCommand,
}

/// The `qp` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum QpCommand {
    /// Certify the solver's worst-case iterations and flops over the parameter box.
    ///
    /// Input: a `kestrel.mpqp.v1` problem (rows bounding one variable
    /// become the solver's simple bounds, mirrored rows double-sided rows).
    /// The parameter box is partitioned by the sequence of active sets the
    /// solver visits from a cold start (and, with `--warm-step`, from the
    /// previous optimal active set, sorted by constraint index or with
    /// `--any-order` in every order, with every parameter moving at most D
    /// times its box width).
    ///
    /// Output: a summary on standard output (worst iterations and flops,
    /// the worst region's interior point, region counts by iterations);
    /// `--json OUT` writes `kestrel.qp-certificate.v1` (`cold`, `warm`: each
    /// with `worst_iterations`, `worst_flops`, `regions`, `histogram`,
    /// `worst_region` {`theta`, `theta_prev`, `path`, `A`, `b`, ...}).
    Certify(CertifyArgs),
    /// Solve the QP exactly at each theta of a CSV file with the dual
    /// active-set solver.
    ///
    /// Input: the problem (`--problem`, `kestrel.mpqp.v1`, mapped as for
    /// `certify`) and a CSV file of parameters (`--thetas`: one theta per
    /// row, p numbers, no header). Every row is a cold start, or with
    /// `--warm` a warm start from the previous row's final active set (the
    /// rows as the periods of a flight, as the firmware solves them). In
    /// f64, or in f32 with `--f32` (and `QpSettings::for_f32`).
    ///
    /// Output (CSV, to stdout or `--out`): one row per theta, the n entries
    /// of z, no header; `--with-iterations` appends the row's active-set
    /// changes (the count `certify` bounds). A summary on standard error.
    /// A theta where the constraints are infeasible, or where the
    /// iteration cap is reached, stops the command naming its line, and
    /// nothing is written. Parameters outside the problem's parameter set
    /// are solved with a warning: the certificate does not cover them.
    Solve(SolveArgs),
}

/// Flags of `kestrel qp solve`.
#[derive(clap::Args, Debug)]
pub struct SolveArgs {
    #[command(flatten)]
    pub input: ProblemThetas,
    /// Warm-start each row from the previous row's final active set (the
    /// first row starts cold).
    #[arg(long)]
    pub warm: bool,
    /// Solve in f32 with the f32 tolerances (`QpSettings::for_f32`).
    #[arg(long)]
    pub f32: bool,
    /// Append each row's active-set changes (iterations) as a last column.
    #[arg(long)]
    pub with_iterations: bool,
    /// Output file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// Flags of `kestrel qp certify`.
#[derive(clap::Args, Debug)]
pub struct CertifyArgs {
    /// Problem file (`kestrel.mpqp.v1`).
    pub problem: PathBuf,
    /// Also certify the warm start for parameter steps up to D times each
    /// parameter's box width (0 < D <= 1).
    #[arg(long, value_name = "D")]
    pub warm_step: Option<f64>,
    /// Certify the warm start from the previous active set in any stored
    /// order (every permutation; sets of at most 8), not only sorted by
    /// constraint index.
    #[arg(long, requires = "warm_step")]
    pub any_order: bool,
    /// Mirror the solver's f32 tolerances (`QpSettings::for_f32`) instead
    /// of the f64 defaults.
    #[arg(long)]
    pub f32_tolerances: bool,
    /// Write the certificate as JSON here.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
    /// Certify over the parameter box scaled by F about its centre (0 < F
    /// <= 1; e.g. 0.1 for a tenth of every parameter's range).
    #[arg(long, value_name = "F", default_value_t = 1.0)]
    pub box_scale: f64,
    /// Random walks of the up-front size estimate (0: none); a partition
    /// estimated beyond --max-regions or four times --time-limit is refused
    /// at once.
    #[arg(long, default_value_t = 64)]
    pub estimate_probes: usize,
    /// Give up after this many regions in one start.
    #[arg(long, default_value_t = 2_000_000)]
    pub max_regions: usize,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 600.0)]
    pub time_limit: f64,
    /// Certify an upper bound instead of the exact partition: merge on
    /// the solver's canonical states (after each full dual step),
    /// remembering H segments of history (default 2; larger is tighter
    /// and slower). For parameter boxes whose exact partition is out of
    /// reach; the certificate says `exact: false`, `--max-regions` limits
    /// the memoised bounds and no up-front estimate is made. Write
    /// `--merge=H` before the problem file.
    #[arg(long, value_name = "H", num_args = 0..=1, default_missing_value = "2", conflicts_with = "any_order")]
    pub merge: Option<usize>,
    /// Exact certificate with regions merged: the regions reaching the
    /// same active set after a full dual step with the same iteration count
    /// are merged where their union is convex (same exact worst-case
    /// iterations, fewer regions; the flops become an upper bound when
    /// merged regions' orders differed). Refused up front, as the exact
    /// mode, when the estimate exceeds the limits.
    #[arg(long, conflicts_with = "merge")]
    pub exact_merge: bool,
}

/// Runs `kestrel qp`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        QpCommand::Certify(a) => run_certify(a),
        QpCommand::Solve(a) => run_solve(a),
    }
}

/// One row's solution and iteration count.
struct Solved {
    z: Vec<f64>,
    iterations: usize,
}

/// Solves the rows in turn in `S` (cold, or warm from the previous row);
/// the first failure names its line.
fn solve_rows<S: QpScalar>(
    qp: &ParametricQp,
    thetas: &NumberedRows,
    warm: bool,
    settings: QpSettings,
    file: &str,
) -> anyhow::Result<Vec<Solved>> {
    let (ns, ni) = qp.workspace_len();
    let (mut scalars, mut indices) = (vec![S::ZERO; ns], vec![0usize; ni]);
    let mut solver = qp
        .solver::<S>(settings, &mut scalars, &mut indices)
        .map_err(|e| anyhow::anyhow!("setting up the solver: {e}"))?;
    let mut buf = qp.buffers::<S>();
    let mut z = vec![S::ZERO; qp.n()];
    let mut out = Vec::with_capacity(thetas.rows.len());
    for (k, (theta, &number)) in thetas.rows.iter().zip(&thetas.lines).enumerate() {
        let line = || format!("{file}: line {number}");
        qp.fill(theta, &mut buf).with_context(line)?;
        let start = if warm && k > 0 {
            Start::Warm
        } else {
            Start::Cold
        };
        let info = solver.solve(&buf.data(), start).map_err(|e| {
            let hint = match e {
                QpError::Infeasible => ": no z meets the constraints at this theta",
                QpError::IterationLimit => ": more active-set changes than the solver's cap",
                _ => "",
            };
            anyhow::anyhow!("{}: {e}{hint}", line())
        })?;
        solver
            .refine(&buf.data())
            .and_then(|()| solver.solution(&mut z))
            .map_err(|e| anyhow::anyhow!("{}: {e}", line()))?;
        out.push(Solved {
            z: z.iter().map(|v| v.to_f64()).collect(),
            iterations: info.iterations,
        });
    }
    Ok(out)
}

fn run_solve(a: SolveArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.out.as_deref()])?;
    let name = a.input.problem.display().to_string();
    let problem = MpqpProblem::read(&a.input.problem).with_context(|| name.clone())?;
    let qp = ParametricQp::from_mpqp(&problem).with_context(|| name.clone())?;
    let file = a.input.thetas.display().to_string();
    let thetas = a.input.read_thetas(qp.p(), qp.n() + 1)?;
    let outside: Vec<usize> = (0..thetas.rows.len())
        .filter(|&k| !qp.contains(&thetas.rows[k], 0.0))
        .collect();
    if let Some(&k) = outside.first() {
        eprintln!(
            "warning: {} of {} parameters lie outside the problem's parameter set, which `kestrel qp certify` covers (first: {file} line {}); they are solved anyway, without a certified iteration count",
            outside.len(),
            thetas.rows.len(),
            thetas.lines[k]
        );
    }
    let solved = if a.f32 {
        solve_rows::<f32>(&qp, &thetas, a.warm, QpSettings::for_f32(), &file)?
    } else {
        solve_rows::<f64>(&qp, &thetas, a.warm, QpSettings::default(), &file)?
    };
    let mut out = String::new();
    for s in &solved {
        let mut cells: Vec<String> =
            s.z.iter()
                .map(|&v| {
                    if a.f32 {
                        format!("{:?}", v as f32)
                    } else {
                        format!("{v:?}")
                    }
                })
                .collect();
        if a.with_iterations {
            cells.push(s.iterations.to_string());
        }
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    if let Some((k, worst)) = solved
        .iter()
        .enumerate()
        .max_by_key(|(k, s)| (s.iterations, std::cmp::Reverse(*k)))
    {
        eprintln!(
            "{} parameters solved ({}, {}): at most {} active-set changes (line {}), {:.2} on average",
            solved.len(),
            if a.warm {
                "warm from the previous row"
            } else {
                "cold"
            },
            if a.f32 { "f32" } else { "f64" },
            worst.iterations,
            thetas.lines[k],
            solved.iter().map(|s| s.iterations as f64).sum::<f64>() / solved.len() as f64
        );
    }
    io::write_output(a.out.as_deref(), &out)
}

fn run_certify(a: CertifyArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.json.as_deref()])?;
    let name = a.problem.display().to_string();
    let mut problem = MpqpProblem::read(&a.problem).with_context(|| name.clone())?;
    anyhow::ensure!(
        a.box_scale > 0.0 && a.box_scale <= 1.0,
        "--box-scale must be in (0, 1]"
    );
    if a.box_scale < 1.0 {
        problem.scale_parameter_box(a.box_scale);
    }
    anyhow::ensure!(
        a.time_limit.is_finite() && a.time_limit > 0.0,
        "--time-limit must be a positive number of seconds"
    );
    let settings = CertifySettings {
        warm_step: a.warm_step,
        warm_any_order: a.any_order,
        qp: if a.f32_tolerances {
            QpSettings::for_f32()
        } else {
            CertifySettings::default().qp
        },
        max_regions: a.max_regions,
        time_limit: Some(Duration::from_secs_f64(a.time_limit)),
        keep_regions: false,
        estimate_probes: a.estimate_probes,
        merge: a.merge,
        union_merge: a.exact_merge,
        ..CertifySettings::default()
    };
    let bar = if progress::enabled() {
        let pb = indicatif::ProgressBar::new_spinner();
        pb.enable_steady_tick(Duration::from_millis(200));
        pb
    } else {
        indicatif::ProgressBar::hidden()
    };
    progress::show(&bar);
    let mut show = |p: &kestrel_empc::certify::Progress| {
        if let Some(e) = p.estimate {
            bar.suspend(|| {
                eprintln!(
                    "note: the cold-start partition is estimated at about {} regions, {} s ({} random walks)",
                    Count(e.regions),
                    Count(e.seconds),
                    e.probes
                )
            });
        }
        bar.set_message(format!(
            "{}: {} {}, {} open, {} LPs, worst {} iterations, start sets {}/{}",
            p.phase,
            p.regions,
            if a.merge.is_some() {
                "merged bounds"
            } else {
                "regions"
            },
            p.open,
            p.lps,
            p.worst_iterations,
            p.start_sets_done,
            p.start_sets
        ));
    };
    let result = certify(&problem, &settings, &mut show);
    bar.finish_and_clear();
    let c = result.with_context(|| name.clone())?;
    let (n, m, p) = (c.cold.n, c.cold.m, c.cold.p);
    let mut text = format!(
        "{name}: n = {n} variables, m = {m} general rows (besides the bounds), p = {p} parameters{}{}\n{}",
        if a.box_scale < 1.0 {
            format!(", parameter box scaled by {}", a.box_scale)
        } else {
            String::new()
        },
        match &problem.theta_poly {
            Some((_, b)) => format!(", the box cut by the {} rows of theta_poly", b.len()),
            None => String::new(),
        },
        c.cold
    );
    if let Some(w) = &c.warm {
        text.push_str(&w.to_string());
    }
    print!("{text}");
    if let Some(out) = &a.json {
        let mut doc = json!({
            "format": "kestrel.qp-certificate.v1",
            "problem": name,
            "box_scale": a.box_scale,
            "cold": c.cold.to_json(),
            "warm": c.warm.as_ref().map(Certificate::to_json),
        });
        if let Some(h) = a.merge {
            doc["merge_history"] = json!(h);
        }
        io::write_output(Some(out), &serde_json::to_string_pretty(&doc)?)?;
    }
    Ok(())
}
