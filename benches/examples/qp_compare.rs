//! kestrel-qp against DAQP's C core, qpOASES, TinyMPC, kestrel-fgm and
//! clarabel, per solve, on the same problems and parameters in one run
//! (issue 24). Run it with `scripts/qp-bench.sh` (it builds the harnesses
//! of `benches/daqp/`, `benches/qpoases/` and `benches/tinympc/` and
//! passes them as `--daqp`, `--qpoases`, `--tinympc`); alone it times the
//! Rust solvers only.
//!
//! Problems: the tricopter thesis-sized problem (`N = 2`, `N_s = 1`, n = 4,
//! 9 parameters) and the larger one (`N = 10`, blocks `[1, 1, 2, 6]`,
//! n = 16), both box only, from the identified model
//! `models/tricopter-blackbox-5.json`, and kestrel-empc's random
//! `testing::thesis_sized(1..=3)`, and the two problems TinyMPC can
//! express (`N = 2` and `N = 10` without blocking, the states rotated for
//! diagonal weights, TinyMPC's terminal weight: `qp_compare/tiny.rs`);
//! each mapped to the solver's form by
//! `kestrel_qp::parametric::ParametricQp` (single-variable rows become
//! simple bounds).
//!
//! Parameters: `--samples` (default 10^4) uniform in the parameter box
//! (cold starts) and a random walk of as many steps of at most 1 % of
//! each parameter's range (warm starts, each from the previous solve).
//! Every solver gets the same inputs: kestrel-qp and DAQP the linear term
//! and bounds at each theta (evaluated before timing), kestrel-fgm and
//! clarabel theta itself (their affine maps are inside their solves).
//! TinyMPC gets theta's state and the input bounds at theta (its problem's
//! references are zero). Each solve is timed on its own (`Instant`, i.e.
//! `clock_gettime`), the table gives the median, the 99th percentile and
//! the maximum. Exits with 1 if DAQP's, qpOASES's, clarabel's or the warm
//! solution differs from kestrel-qp's cold f64 one by more than 1e-9
//! relative, or one of those solves fails (TinyMPC and the FGM are not
//! exact: their deviation is reported, not checked).
//!
//! `cargo run --release -p kestrel-benches --example qp_compare --
//! [--samples N] [--daqp PATH_TO_daqp_bench] [--qpoases PATH_TO_qpoases_bench]
//! [--tinympc PATH_TO_tinympc_bench] [--rho TINYMPC_RHO] [--dir DIR]`

#[path = "qp_compare/tiny.rs"]
mod tiny;

use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_fgm::{
    AppliedInputs, BoxQp, FgmData, FgmDesign, FgmSettings, Momentum, WorkspaceMut, solve_view,
};
use kestrel_mpc::{QpSettings as RefSettings, ReferenceSolver};
use kestrel_qp::parametric::{ParametricQp, QpBuffers};
use kestrel_qp::{QpScalar, QpSettings, Start};
use kestrel_tricopter::{ProblemSize, default_weights, tricopter_problem};
use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Timing of one solver on one sample set.
struct Stats {
    median: u64,
    p99: u64,
    max: u64,
    mean_iter: f64,
    max_iter: usize,
    /// Largest deviation from the kestrel-qp f64 solution (relative,
    /// `|z - z_ref|_inf / (1 + |z_ref|_inf)`).
    deviation: f64,
    failures: usize,
}

fn stats(mut ns: Vec<u64>, iters: &[usize], deviation: f64, failures: usize) -> Stats {
    ns.sort_unstable();
    let count = ns.len();
    Stats {
        median: ns[count / 2],
        p99: ns[(count - 1) * 99 / 100],
        max: ns[count - 1],
        mean_iter: iters.iter().sum::<usize>() as f64 / iters.len().max(1) as f64,
        max_iter: iters.iter().copied().max().unwrap_or(0),
        deviation,
        failures,
    }
}

fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = 1.0 + b.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0_f64, |s, (x, y)| s.max((x - y).abs() / scale))
}

/// TinyMPC's ADMM penalty (`--rho`): of 1e-2, 1e-1, 1, 10 and 100, the one
/// with the fewest iterations for cold starts at TinyMPC's default
/// tolerance on the N = 10 problem (1e-2 takes fewer warm, more cold).
const TINY_RHO: f64 = 0.1;

/// TinyMPC's configurations: `(label, absolute primal and dual tolerance,
/// max_iter)`, its defaults and a tight one.
const TINY_CONFIGS: [(&str, f64, usize); 2] = [("default", 1e-3, 1000), ("tight", 1e-8, 100_000)];

/// The identified model `models/tricopter-blackbox-5.json`.
fn identified_model() -> SsModel {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../models/tricopter-blackbox-5.json"
    );
    SsModel::read(Path::new(path)).expect("identified model")
}

fn tricopter(size: ProblemSize) -> MpqpProblem {
    let model = identified_model();
    let (q1, q2) = default_weights();
    tricopter_problem(&model, size, q1, q2)
        .expect("tricopter problem")
        .to_mpqp()
}

/// The two parameter sets: uniform (cold) and a 1 % random walk (warm).
fn parameter_sets(p: &MpqpProblem, count: usize, seed: u64) -> [Vec<Vec<f64>>; 2] {
    let mut rng = SplitMix64::seed_from_u64(seed);
    let (lb, ub) = (&p.theta_lb, &p.theta_ub);
    let uniform = (0..count)
        .map(|_| {
            (0..p.p())
                .map(|j| lb[j] + (ub[j] - lb[j]) * rng.random::<f64>())
                .collect()
        })
        .collect();
    let mut theta: Vec<f64> = (0..p.p()).map(|j| 0.5 * (lb[j] + ub[j])).collect();
    let walk = (0..count)
        .map(|_| {
            for (j, t) in theta.iter_mut().enumerate() {
                let step = 0.01 * (ub[j] - lb[j]) * (2.0 * rng.random::<f64>() - 1.0);
                *t = (*t + step).clamp(lb[j], ub[j]);
            }
            theta.clone()
        })
        .collect();
    [uniform, walk]
}

/// kestrel-qp in `S` on one set: per-solve times, iterations, solutions.
fn time_qp<S: QpScalar>(
    par: &ParametricQp,
    settings: QpSettings,
    inputs: &[QpBuffers<S>],
    start: Start,
) -> (Vec<u64>, Vec<usize>, Vec<Vec<f64>>, usize) {
    let (ns, ni) = par.workspace_len();
    let (mut s, mut ix) = (vec![S::ZERO; ns], vec![0usize; ni]);
    let mut qp = par.solver::<S>(settings, &mut s, &mut ix).expect("set-up");
    let n = par.n();
    let mut z = vec![S::ZERO; n];
    let (mut times, mut iters, mut sols, mut failures) = (vec![], vec![], vec![], 0);
    qp.set_active_set(&[]).expect("empty set");
    for buf in inputs {
        let data = buf.data();
        let t0 = Instant::now();
        let r = qp.solve(black_box(&data), start);
        let ok = r.is_ok() && qp.solution(&mut z).is_ok();
        let t = t0.elapsed().as_nanos() as u64;
        times.push(t);
        match r {
            Ok(info) if ok => {
                iters.push(info.iterations);
                sols.push(z.iter().map(|v| v.to_f64()).collect());
            }
            _ => {
                failures += 1;
                sols.push(vec![f64::NAN; n]);
            }
        }
    }
    (times, iters, sols, failures)
}

/// kestrel-fgm (f64, the certified iteration count, cold start from the
/// box centre) on one set.
fn time_fgm(data: &FgmData<f64>, thetas: &[Vec<f64>], zref: &[Vec<f64>]) -> Stats {
    let n = data.n;
    let view = data.view();
    let mut buf = vec![0.0; 6 * n];
    let mut out = vec![0.0; n];
    let (mut times, mut worst, mut failures) = (vec![], 0.0_f64, 0);
    for (theta, zr) in thetas.iter().zip(zref) {
        let (lo, rest) = buf.split_at_mut(n);
        let (hi, rest) = rest.split_at_mut(n);
        let (c, rest) = rest.split_at_mut(n);
        let (z, rest) = rest.split_at_mut(n);
        let (y, w) = rest.split_at_mut(n);
        let t0 = Instant::now();
        let r = solve_view(
            &view,
            black_box(theta),
            kestrel_fgm::Start::Cold,
            data.iterations,
            WorkspaceMut { lo, hi, c, z, y, w },
            &mut out,
        );
        times.push(t0.elapsed().as_nanos() as u64);
        if r.is_ok() {
            worst = worst.max(relative(&out, zr));
        } else {
            failures += 1;
        }
    }
    let iters = vec![data.iterations; thetas.len()];
    stats(times, &iters, worst, failures)
}

/// clarabel (kestrel-mpc's ReferenceSolver, default settings: polished).
fn time_clarabel(p: &MpqpProblem, thetas: &[Vec<f64>], zref: &[Vec<f64>]) -> Stats {
    let mut s = ReferenceSolver::new(p, RefSettings::default()).expect("clarabel");
    let (mut times, mut iters, mut worst, mut failures) = (vec![], vec![], 0.0_f64, 0);
    for (theta, zr) in thetas.iter().zip(zref) {
        let th = DVector::from_column_slice(theta);
        let t0 = Instant::now();
        let r = s.solve(black_box(&th));
        times.push(t0.elapsed().as_nanos() as u64);
        match r {
            Ok(sol) => {
                iters.push(sol.iterations as usize);
                worst = worst.max(relative(sol.z.as_slice(), zr));
            }
            Err(_) => failures += 1,
        }
    }
    stats(times, &iters, worst, failures)
}

/// One sample set for the DAQP harness: its label (`cold` or `warm`), the
/// inputs, kestrel-qp's solutions and iterations.
type Set<'a> = (&'a str, &'a [QpBuffers<f64>], &'a [Vec<f64>], &'a [usize]);

/// Writes one problem and its two sets (inputs, kestrel-qp's f64
/// solution and iterations) for the DAQP harness.
fn write_problem(path: &Path, name: &str, par: &ParametricQp, sets: &[Set<'_>]) {
    let mut out = String::new();
    let (n, m) = (par.n(), par.m());
    let _ = writeln!(out, "{name} {n} {m} {}", sets.len());
    let line = |v: &[f64], out: &mut String| {
        for x in v {
            let _ = write!(out, "{x:e} ");
        }
        out.push('\n');
    };
    line(par.h(), &mut out);
    line(par.g(), &mut out);
    for (label, inputs, sols, iters) in sets {
        let _ = writeln!(out, "{label} {}", inputs.len());
        for ((b, z), it) in inputs.iter().zip(sols.iter()).zip(iters.iter()) {
            for v in [&b.q, &b.l, &b.u, &b.lb, &b.ub] {
                line(v, &mut out);
            }
            line(z, &mut out);
            let _ = writeln!(out, "{it}");
        }
    }
    std::fs::write(path, out).expect("write the DAQP input");
}

/// Runs one C/C++ harness (DAQP's, qpOASES's, TinyMPC's) on its input
/// file: `(label, Stats)` per line `<tag> <name> <label> <count> <median>
/// <p99> <max> <mean_iter> <max_iter> <deviation> <failures>`.
fn run_harness(bin: &Path, file: &Path, tag: &str) -> Vec<(String, Stats)> {
    let out = Command::new(bin)
        .arg(file)
        .output()
        .unwrap_or_else(|e| panic!("run {}: {e}", bin.display()));
    assert!(out.status.success(), "{} failed: {out:?}", bin.display());
    let text = String::from_utf8_lossy(&out.stdout);
    if let Some(t) = text.lines().find_map(|l| l.strip_prefix("timer ")) {
        eprintln!("  DAQP harness: an empty timed interval takes {t} ns (median)");
    }
    text.lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f.len() == 11 && f[0] == tag).then(|| {
                let num = |i: usize| f[i].parse::<f64>().unwrap_or(f64::NAN);
                (
                    f[2].to_string(),
                    Stats {
                        median: num(4) as u64,
                        p99: num(5) as u64,
                        max: num(6) as u64,
                        mean_iter: num(7),
                        max_iter: num(8) as usize,
                        deviation: num(9),
                        failures: num(10) as usize,
                    },
                )
            })
        })
        .collect()
}

struct Args {
    samples: usize,
    daqp: Option<PathBuf>,
    qpoases: Option<PathBuf>,
    tinympc: Option<PathBuf>,
    /// TinyMPC's ADMM penalty.
    rho: f64,
    dir: PathBuf,
}

fn args() -> Args {
    let mut a = Args {
        samples: 10_000,
        daqp: None,
        qpoases: None,
        tinympc: None,
        rho: TINY_RHO,
        dir: std::env::temp_dir().join("kestrel-qp-bench"),
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        match flag.as_str() {
            "--samples" => a.samples = value.parse().expect("--samples N"),
            "--daqp" => a.daqp = Some(PathBuf::from(value)),
            "--qpoases" => a.qpoases = Some(PathBuf::from(value)),
            "--tinympc" => a.tinympc = Some(PathBuf::from(value)),
            "--rho" => a.rho = value.parse().expect("--rho R"),
            "--dir" => a.dir = PathBuf::from(value),
            other => panic!("unknown flag {other}"),
        }
    }
    a
}

/// The FGM's accuracy: 1 us on the first move's pulses for the
/// tricopter problems (as the `fgm` bench), 1e-3 on every variable for
/// the random ones (scaled units).
fn fgm_data(p: &MpqpProblem, max_error: f64) -> FgmData<f64> {
    let qp = BoxQp::from_mpqp(p).expect("box QP");
    let d = FgmDesign::new(
        qp,
        FgmSettings {
            momentum: Momentum::Constant,
            ..FgmSettings::default()
        },
    )
    .expect("FGM design");
    let first = 4.min(d.n());
    let tol = d
        .input_tolerance(max_error, AppliedInputs::FirstMove(first))
        .expect("tolerance");
    let cert = d.certify(tol.eps).expect("certificate");
    d.data::<f64>(&cert, None).expect("FGM data")
}

fn main() {
    let a = args();
    std::fs::create_dir_all(&a.dir).expect("output directory");
    let tiny = |horizon: usize| {
        let t = tiny::tiny_problem(&identified_model(), horizon, a.rho);
        (
            format!("tricopter-N{horizon}-unblocked"),
            t.mpqp.clone(),
            1.0,
            Some(t),
        )
    };
    let problems: Vec<(String, MpqpProblem, f64, Option<tiny::TinyProblem>)> = [
        (
            "tricopter-thesis".to_string(),
            tricopter(ProblemSize::Thesis),
            1.0,
            None,
        ),
        (
            "tricopter-larger".to_string(),
            tricopter(ProblemSize::Larger),
            1.0,
            None,
        ),
    ]
    .into_iter()
    .chain((1..=3).map(|seed| {
        (
            format!("empc-thesis_sized({seed})"),
            kestrel_empc::testing::thesis_sized(seed),
            1e-3,
            None,
        )
    }))
    .chain([tiny(2), tiny(10)])
    .collect();
    let mut table = String::new();
    // Problems where the exact solvers disagree or fail (checked below).
    let mut mismatches: Vec<String> = vec![];
    let _ = writeln!(
        table,
        "| problem | solver | start | median ns | p99 ns | max ns | iterations mean / max | median vs DAQP | max deviation |"
    );
    let _ = writeln!(table, "|---|---|---|---|---|---|---|---|---|");
    for (pi, (name, p, fgm_error, tiny)) in problems.iter().enumerate() {
        let par = ParametricQp::from_mpqp(p).expect("parametric QP");
        let mut sets = parameter_sets(p, a.samples, 24 + pi as u64);
        if let Some(t) = tiny {
            for set in &mut sets {
                t.zero_references(set);
            }
        }
        let fill = |thetas: &[Vec<f64>]| -> (Vec<QpBuffers<f64>>, Vec<QpBuffers<f32>>) {
            thetas
                .iter()
                .map(|t| {
                    let (mut b64, mut b32) = (par.buffers::<f64>(), par.buffers::<f32>());
                    par.fill(t, &mut b64).expect("fill");
                    par.fill(t, &mut b32).expect("fill");
                    (b64, b32)
                })
                .unzip()
        };
        let (cold64, cold32) = fill(&sets[0]);
        let (warm64, warm32) = fill(&sets[1]);
        eprintln!(
            "{name}: n = {} (all bounded), m = {} general rows, p = {}, {} theta per set",
            par.n(),
            par.m(),
            par.p(),
            a.samples
        );
        let f64s = QpSettings::default();
        let f32s = QpSettings::for_f32();
        // One untimed pass warms the caches and the branch predictors.
        let _ = time_qp(&par, f64s, &cold64[..cold64.len().min(1000)], Start::Cold);
        let (tc, ic, zc, fc) = time_qp(&par, f64s, &cold64, Start::Cold);
        let (tw, iw, zw, fw) = time_qp(&par, f64s, &warm64, Start::Warm);
        let (tc32, ic32, zc32, fc32) = time_qp(&par, f32s, &cold32, Start::Cold);
        let (tw32, iw32, zw32, fw32) = time_qp(&par, f32s, &warm32, Start::Warm);
        let dev = |a: &[Vec<f64>], b: &[Vec<f64>]| {
            a.iter()
                .zip(b)
                .fold(0.0_f64, |s, (x, y)| s.max(relative(x, y)))
        };
        // Cold and warm solves agree (same QP, different starts).
        let cold_warm = dev(&zw, &time_qp(&par, f64s, &warm64, Start::Cold).2);
        let mut rows: Vec<(&str, &str, Stats)> = vec![
            ("kestrel-qp f64", "cold", stats(tc, &ic, 0.0, fc)),
            ("kestrel-qp f64", "warm", stats(tw, &iw, cold_warm, fw)),
            (
                "kestrel-qp f32",
                "cold",
                stats(tc32, &ic32, dev(&zc32, &zc), fc32),
            ),
            (
                "kestrel-qp f32",
                "warm",
                stats(tw32, &iw32, dev(&zw32, &zw), fw32),
            ),
        ];
        let mut daqp: Vec<(String, Stats)> = vec![];
        let mut qpoases: Vec<(String, Stats)> = vec![];
        let file = a.dir.join(format!("{name}.txt"));
        if a.daqp.is_some() || a.qpoases.is_some() {
            write_problem(
                &file,
                name,
                &par,
                &[("cold", &cold64, &zc, &ic), ("warm", &warm64, &zw, &iw)],
            );
        }
        if let Some(bin) = &a.daqp {
            daqp = run_harness(bin, &file, "daqp");
        }
        if let Some(bin) = &a.qpoases {
            qpoases = run_harness(bin, &file, "qpoases");
        }
        // All three solve the same QP: DAQP's and qpOASES's solutions are
        // kestrel-qp's.
        for (solver, label, st) in daqp
            .iter()
            .map(|(l, s)| ("DAQP", l, s))
            .chain(qpoases.iter().map(|(l, s)| ("qpOASES", l, s)))
        {
            if st.deviation > 1e-9 || st.deviation.is_nan() || st.failures > 0 {
                mismatches.push(format!("{name}: {solver} {label}"));
            }
        }
        let mut tinympc: Vec<(String, Stats)> = vec![];
        if let (Some(bin), Some(t)) = (&a.tinympc, tiny) {
            let tfile = a.dir.join(format!("{name}.tinympc.txt"));
            t.write(
                &tfile,
                name,
                &TINY_CONFIGS,
                &[
                    ("cold", &sets[0], &cold64, &zc),
                    ("warm", &sets[1], &warm64, &zw),
                ],
            );
            tinympc = run_harness(bin, &tfile, "tinympc");
        }
        let fgm = fgm_data(p, *fgm_error);
        rows.push(("kestrel-fgm f64", "cold", time_fgm(&fgm, &sets[0], &zc)));
        rows.push(("clarabel", "-", time_clarabel(p, &sets[0], &zc)));
        for (solver, start, st) in &rows {
            // Exact solvers: kestrel-qp f64 (warm against cold) and clarabel.
            let exact = solver.starts_with("kestrel-qp f64") || *solver == "clarabel";
            if st.failures > 0 || (exact && st.deviation > 1e-9) {
                mismatches.push(format!("{name}: {solver} {start}"));
            }
        }
        let daqp_median = |start: &str| {
            daqp.iter()
                .find(|(l, _)| l == start)
                .map(|(_, s)| s.median as f64)
        };
        let mut emit = |solver: &str, start: &str, s: &Stats| {
            let ratio = match daqp_median(if start == "warm" { "warm" } else { "cold" }) {
                Some(d) if d > 0.0 => format!("{:.2}", s.median as f64 / d),
                _ => "-".to_string(),
            };
            let fails = if s.failures > 0 {
                format!(" ({} failed)", s.failures)
            } else {
                String::new()
            };
            let _ = writeln!(
                table,
                "| {name} | {solver} | {start} | {} | {} | {} | {:.2} / {} | {ratio} | {:.1e}{fails} |",
                s.median, s.p99, s.max, s.mean_iter, s.max_iter, s.deviation
            );
        };
        for (label, s) in &daqp {
            emit("DAQP 0.11.0 (C)", label, s);
        }
        for (label, s) in &qpoases {
            let (opts, start) = label.split_once('-').unwrap_or(("?", label));
            emit(&format!("qpOASES 3.2.2 ({opts} options)"), start, s);
        }
        for (solver, start, s) in &rows {
            emit(solver, start, s);
        }
        for (label, s) in &tinympc {
            let (cfg, start) = label.split_once('-').unwrap_or(("?", label));
            let tol = TINY_CONFIGS
                .iter()
                .find(|c| c.0 == cfg)
                .map_or(f64::NAN, |c| c.1);
            emit(&format!("TinyMPC 0.0.8 (tol {tol:e})"), start, s);
        }
    }
    // The clock's own cost: the median of an empty timed interval.
    let mut empty: Vec<u64> = (0..100_000)
        .map(|_| {
            let t0 = Instant::now();
            black_box(());
            t0.elapsed().as_nanos() as u64
        })
        .collect();
    empty.sort_unstable();
    println!("{table}");
    println!(
        "timer: an empty timed interval takes {} ns (median; Instant, i.e. clock_gettime(CLOCK_MONOTONIC)), included in every figure above, DAQP's included.",
        empty[empty.len() / 2]
    );
    println!(
        "median vs DAQP: the solver's median over DAQP's (same start; clarabel, the FGM, qpOASES init and TinyMPC cold against DAQP cold); < 1 is faster. max deviation: from kestrel-qp f64's solution at the same theta (kestrel-qp warm: from its own cold solve), relative |z - z_ref|_inf / (1 + |z_ref|_inf). Iterations: active-set changes for kestrel-qp, DAQP's own count (its loop passes), qpOASES's nWSR (working-set changes), ADMM iterations for TinyMPC ('failed': not converged within max_iter), the certified count for the FGM, interior-point iterations for clarabel. qpOASES cold: hotstart from the empty working set (H's factor kept); init: init() from scratch. TinyMPC ({TINY_CONFIGS:?}, rho = {}) only on the unblocked problems.",
        a.rho
    );
    if !mismatches.is_empty() {
        eprintln!("solutions differ by more than 1e-9 relative, or solves failed: {mismatches:?}");
        std::process::exit(1);
    }
}
