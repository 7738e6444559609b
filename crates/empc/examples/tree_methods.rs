//! Builds the first-move search tree of a problem with both tree methods
//! and reports size, build time (wall and CPU) and exactness:
//! `cargo run --release -p kestrel-empc --features parallel --example
//! tree_methods -- [problem.json|thesis] [first_move] [lp|sampled|both] [samples]
//! [shrink] [max_nodes]` (`shrink` < 1 scales the parameter box about its
//! centre). The tables are those of `build_any` (`TreeLayout::Auto`: `u16`
//! when the tree fits, else the wide `u32` layout); the example also times
//! the evaluation (f64 and f32 tables) over the sample parameters.
//!
//! Exactness: at `samples` (default 10^4) random parameters in the box,
//! the tree's output equals the law of a region containing the parameter
//! (the mpQP solution's own region lookup) to 1e-8 (relative to the
//! output's size); every parameter must be covered by a region.
#[path = "../tests/common/mod.rs"]
mod common;
mod shared;

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::tree::{TreeMethod, build_any};
use kestrel_empc::{Outputs, Settings, TreeSettings, solve};
use shared::{cpu_seconds, eval_times};

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "thesis".into());
    let k: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(4);
    let which = args.next().unwrap_or_else(|| "both".into());
    let samples: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(10_000);
    let shrink: f64 = args.next().and_then(|v| v.parse().ok()).unwrap_or(1.0);
    let max_nodes: Option<usize> = args.next().and_then(|v| v.parse().ok());
    let mut prob = if path == "thesis" {
        kestrel_empc::testing::thesis_sized(1)
    } else {
        MpqpProblem::read(std::path::Path::new(&path)).expect("problem")
    };
    prob.scale_parameter_box(shrink);
    let t0 = std::time::Instant::now();
    let sol = solve(&prob, &Settings::default()).expect("solve");
    println!(
        "p {} n {}: {} regions, solve {:.3} s",
        prob.p(),
        prob.n(),
        sol.regions.len(),
        t0.elapsed().as_secs_f64()
    );
    let methods: &[(&str, TreeMethod)] = match which.as_str() {
        "lp" => &[("lp", TreeMethod::Lp)],
        "sampled" => &[("sampled", TreeMethod::Sampled)],
        _ => &[("lp", TreeMethod::Lp), ("sampled", TreeMethod::Sampled)],
    };
    let mut seed: u64 = 0x2545_F491_4F6C_DD1D;
    let xorshift = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let thetas = common::box_samples_with(
        sol.theta_lb.as_slice(),
        sol.theta_ub.as_slice(),
        samples,
        xorshift,
    );
    for &(name, method) in methods {
        let settings = TreeSettings {
            outputs: Outputs::First(k),
            method,
            max_nodes: max_nodes.unwrap_or(TreeSettings::default().max_nodes),
            ..TreeSettings::default()
        };
        let (w, c) = (std::time::Instant::now(), cpu_seconds());
        let ctl = match build_any(&prob, &sol, &settings) {
            Ok(c) => c,
            Err(e) => {
                println!("{name}: {e}");
                continue;
            }
        };
        let (wall, cpu) = (w.elapsed().as_secs_f64(), cpu_seconds() - c);
        let s = &ctl.stats;
        println!(
            "{name}: {} layout, {} laws, {} rows, depth {}, {} nodes, {} hyperplanes, {} bytes f32 ({} with 2-byte numbers), ambiguous {}, build {wall:.2} s wall, {cpu:.2} s CPU",
            if ctl.tables.is_wide() {
                "wide u32"
            } else {
                "u16"
            },
            s.distinct_laws,
            s.distinct_rows,
            s.depth,
            s.nodes,
            s.hyperplanes,
            ctl.tables.bytes(4),
            ctl.tables.bytes(2),
            s.ambiguous_leaves
        );
        let (mut bad, mut uncovered, mut worst) = (0, 0, 0.0_f64);
        let mut z = vec![0.0; k];
        for th in &thetas {
            let Some(want) = sol.first_outputs_at(th, k) else {
                uncovered += 1;
                continue;
            };
            let ok = ctl.tables.evaluate_f64(th, &mut z).is_ok();
            let dev = common::rel(&want, &z);
            worst = worst.max(dev);
            if !ok || dev > 1e-8 {
                bad += 1;
            }
        }
        println!(
            "{name}: {samples} thetas, {bad} mismatches, {uncovered} uncovered, worst relative deviation {worst:.1e}"
        );
        let (t64, t32) = eval_times(&ctl.tables, &thetas);
        println!(
            "{name}: evaluation {:.0} ns (f64), {:.0} ns (f32) per parameter (best of 3 passes over the {samples})",
            t64 * 1e9,
            t32 * 1e9
        );
    }
}
