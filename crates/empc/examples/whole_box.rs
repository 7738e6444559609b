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

mod shared;

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::tree::{TreeMethod, build_any};
use kestrel_empc::{Outputs, Settings, TreeSettings, solve};
use shared::{SweepArgs, cpu_seconds, eval_times};

fn main() {
    let mut args = std::env::args().skip(1);
    let SweepArgs {
        path,
        first_move: k,
        samples,
        every,
    } = SweepArgs::read(&mut args);
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
    let thetas = common::box_samples(
        prob.theta_lb.as_slice(),
        prob.theta_ub.as_slice(),
        samples,
        2026,
    );
    let (mut bad, mut uncovered, mut worst) = (0, 0, 0.0_f64);
    let (mut cl_n, mut cl_bad, mut cl_worst, mut cl_failed) = (0, 0, 0.0_f64, 0);
    let mut cl_law_better = 0;
    let mut z = vec![0.0; k];
    for (i, th) in thetas.iter().enumerate() {
        let ok = ctl.tables.evaluate_f64(th, &mut z).is_ok();
        let Some(want) = sol.first_outputs_at(th, k) else {
            uncovered += 1;
            continue;
        };
        let d = common::rel(&want, &z);
        worst = worst.max(d);
        if !ok || d > 1e-9 {
            bad += 1;
        }
        if every > 0 && i % every == 0 {
            cl_n += 1;
            match common::clarabel_qp_checked(&prob, th) {
                Ok(Some(x)) => {
                    let dc = common::rel(&x[..k], &z);
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
    let (t64, t32) = eval_times(&ctl.tables, &thetas);
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
        std::fs::write(&o, kestrel_empc::export::solution_json(&sol, &ctl, false))
            .expect("write the solution file");
        println!("solution file: {o}");
    }
}
