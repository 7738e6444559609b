//! The exact first-move search tree of a problem over its whole parameter
//! box, in the layout that holds it (`build_any`, `TreeLayout::Auto`:
//! `u16` when it fits, else the wide `u32` layout), checked and measured:
//!
//! `cargo run --release -p kestrel-empc --features parallel --example
//! whole_box -- problem.json [first_move] [samples] [clarabel_every]
//! [solution_out.json]`
//!
//! Prints one table row: regions, first-move laws, depth, nodes, bytes
//! (f32 tables), build time (wall and CPU of this process), host
//! evaluation time per parameter (f64 and f32 tables, best of three
//! passes over the samples). Exactness: at `samples` (default 10^4)
//! random parameters in the box the tree's output equals the solution's
//! own region lookup (the law of a region containing the parameter) to
//! 1e-9 relative, every parameter is covered by a region, and every
//! `clarabel_every`-th (default 50) parameter is within 1e-8 (relative to
//! 1 + |z|) of clarabel's solution of the QP or, where not, the law's full
//! `z` is feasible with an objective not above clarabel's (clarabel stopped
//! short; the QP is strictly convex). The last argument writes the
//! solution file (`kestrel empc solve --no-regions` format) for `kestrel
//! empc eval` / `export`.

#[path = "../tests/common/mod.rs"]
mod common;

use kestrel_core::Scalar;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::eval::{TreeIndex, TreeTables};
use kestrel_empc::mpqp::Rng;
use kestrel_empc::tree::{AnyTables, TreeMethod, build_any};
use kestrel_empc::{Outputs, Settings, TreeSettings, evaluate_with, solve};

/// CPU seconds of this process (user + system), from `/proc/self/stat`.
fn cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let f: Vec<&str> = s
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let t = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (t(11) + t(12)) / 100.0
}

/// Mean seconds per evaluation over `thetas` (best of three passes).
fn eval_time<S: Scalar, I: TreeIndex, T: TreeTables<S, I>>(t: &T, thetas: &[Vec<f64>]) -> f64 {
    let ths: Vec<Vec<S>> = thetas
        .iter()
        .map(|th| th.iter().map(|&v| S::from_f64(v)).collect())
        .collect();
    let mut z = vec![S::ZERO; t.n_outputs()];
    let mut scratch = vec![S::ZERO; t.n_params()];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let w = std::time::Instant::now();
        for th in &ths {
            let e = evaluate_with(t, std::hint::black_box(th), &mut scratch, &mut z);
            std::hint::black_box((&e, &z));
        }
        best = best.min(w.elapsed().as_secs_f64() / ths.len().max(1) as f64);
    }
    best
}

/// Evaluates either layout in f64.
fn eval_any(t: &AnyTables, th: &[f64], scratch: &mut [f64], z: &mut [f64]) -> bool {
    match t {
        AnyTables::Narrow(t) => evaluate_with(&t.tables(), th, scratch, z).is_ok(),
        AnyTables::Wide(t) => evaluate_with(&t.tables(), th, scratch, z).is_ok(),
    }
}

fn rel(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (1.0 + x.abs()))
        .fold(0.0, f64::max)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("a problem file");
    let k: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(4);
    let samples: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(10_000);
    let every: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(50);
    let out = args.next();
    let prob = MpqpProblem::read(std::path::Path::new(&path)).expect("problem");
    let (w0, c0) = (std::time::Instant::now(), cpu_seconds());
    let sol = solve(&prob, &Settings::default()).expect("solve");
    println!(
        "{path}: p {} n {}, {} regions, solve {:.2} s wall, {:.2} s CPU",
        prob.p(),
        prob.n(),
        sol.regions.len(),
        w0.elapsed().as_secs_f64(),
        cpu_seconds() - c0
    );
    let settings = TreeSettings {
        outputs: Outputs::First(k),
        method: TreeMethod::Sampled,
        ..TreeSettings::default()
    };
    let (w1, c1) = (std::time::Instant::now(), cpu_seconds());
    let ctl = build_any(&prob, &sol, &settings).expect("tree");
    let (wall, cpu) = (w1.elapsed().as_secs_f64(), cpu_seconds() - c1);
    let s = &ctl.stats;
    println!(
        "tree: {} layout, {} laws, {} rows, depth {}, {} nodes, {} hyperplanes, {} bytes (f32), ambiguous {}, build {wall:.1} s wall, {cpu:.1} s CPU",
        if ctl.tables.is_wide() { "u32" } else { "u16" },
        s.distinct_laws,
        s.distinct_rows,
        s.depth,
        s.nodes,
        s.hyperplanes,
        ctl.tables.bytes(4),
        s.ambiguous_leaves
    );
    let p = prob.p();
    let mut rng = Rng::new(2026);
    let thetas: Vec<Vec<f64>> = (0..samples)
        .map(|_| {
            (0..p)
                .map(|j| {
                    let (lo, hi) = (prob.theta_lb[j], prob.theta_ub[j]);
                    lo + (hi - lo) * 0.5 * (rng.sym() + 1.0)
                })
                .collect()
        })
        .collect();
    let (mut bad, mut uncovered, mut worst) = (0, 0, 0.0_f64);
    let (mut cl_n, mut cl_bad, mut cl_worst, mut cl_failed) = (0, 0, 0.0_f64, 0);
    let mut cl_law_better = 0;
    let (mut z, mut scratch) = (vec![0.0; k], vec![0.0; p]);
    for (i, th) in thetas.iter().enumerate() {
        let ok = eval_any(&ctl.tables, th, &mut scratch, &mut z);
        let Some(want) = sol.first_outputs_at(th, k) else {
            uncovered += 1;
            continue;
        };
        let d = rel(&want, &z);
        worst = worst.max(d);
        if !ok || d > 1e-9 {
            bad += 1;
        }
        if every > 0 && i % every == 0 {
            cl_n += 1;
            match common::clarabel_qp_checked(&prob, th) {
                Ok(Some(x)) => {
                    let dc = rel(&x[..k], &z);
                    cl_worst = cl_worst.max(dc);
                    if dc > 1e-8 {
                        // Which is the optimum: the law's full z (the
                        // region containing theta) or clarabel's?
                        let full = sol.locate(th, 1e-9).map(|r| sol.regions[r].z(th));
                        if full.is_some_and(|f| {
                            common::law_at_least_as_good(&prob, th, f.as_slice(), &x)
                        }) {
                            cl_law_better += 1;
                        } else {
                            cl_bad += 1;
                        }
                    }
                }
                Ok(None) => cl_bad += 1,
                // clarabel did not converge at its tight tolerances: not
                // a comparison, counted apart.
                Err(_) => cl_failed += 1,
            }
        }
    }
    println!(
        "exactness: {samples} parameters, {bad} mismatches (worst {worst:.1e}), {uncovered} uncovered; clarabel at {cl_n}: {cl_bad} beyond 1e-8 with the law not the better point, {cl_law_better} beyond 1e-8 where the law is feasible with a lower objective (clarabel short; worst difference {cl_worst:.1e}), {cl_failed} where clarabel did not converge"
    );
    let (t64, t32) = match &ctl.tables {
        AnyTables::Narrow(t) => (
            eval_time(&t.tables(), &thetas),
            eval_time(&t.cast::<f32>().tables(), &thetas),
        ),
        AnyTables::Wide(t) => (
            eval_time(&t.tables(), &thetas),
            eval_time(&t.cast::<f32>().tables(), &thetas),
        ),
    };
    println!(
        "evaluation: {:.0} ns (f64), {:.0} ns (f32) per parameter",
        t64 * 1e9,
        t32 * 1e9
    );
    println!(
        "| {path} | {} | {} | {} | {} | {} | {wall:.0} / {cpu:.0} | {:.2} |",
        s.regions,
        s.distinct_laws,
        s.depth,
        s.nodes,
        ctl.tables.bytes(4),
        t32 * 1e6
    );
    if let Some(o) = out {
        std::fs::write(
            &o,
            kestrel_empc::export::solution_json_any(&sol, &ctl, false),
        )
        .expect("write the solution file");
        println!("solution file: {o}");
    }
}
