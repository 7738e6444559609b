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
use kestrel_core::Scalar;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::eval::{TreeIndex, TreeTables};
use kestrel_empc::tree::{AnyTables, TreeMethod, build_any};
use kestrel_empc::{Outputs, Settings, TreeSettings, evaluate_with, solve};

/// Mean seconds per evaluation of `tables` over `thetas` (three passes, the best).
fn eval_time<S: Scalar, I: TreeIndex, T: TreeTables<S, I>>(
    tables: &T,
    thetas: &[Vec<f64>],
    k: usize,
) -> f64 {
    let ths: Vec<Vec<S>> = thetas
        .iter()
        .map(|t| t.iter().map(|&v| S::from_f64(v)).collect())
        .collect();
    let mut z = vec![S::ZERO; k];
    let mut scratch = vec![S::ZERO; tables.n_params()];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = std::time::Instant::now();
        for th in &ths {
            let e = evaluate_with(tables, std::hint::black_box(th), &mut scratch, &mut z);
            std::hint::black_box((&e, &z));
        }
        best = best.min(t.elapsed().as_secs_f64() / ths.len().max(1) as f64);
    }
    best
}

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
    let p = prob.p();
    let mut seed: u64 = 0x2545_F491_4F6C_DD1D;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let thetas: Vec<Vec<f64>> = (0..samples)
        .map(|_| {
            (0..p)
                .map(|j| sol.theta_lb[j] + rnd() * (sol.theta_ub[j] - sol.theta_lb[j]))
                .collect()
        })
        .collect();
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
        let mut scratch = vec![0.0; p];
        for th in &thetas {
            let Some(want) = sol.first_outputs_at(th, k) else {
                uncovered += 1;
                continue;
            };
            let ok = match &ctl.tables {
                AnyTables::Narrow(t) => {
                    evaluate_with(&t.tables(), th, &mut scratch, &mut z).is_ok()
                }
                AnyTables::Wide(t) => evaluate_with(&t.tables(), th, &mut scratch, &mut z).is_ok(),
            };
            let dev = want
                .iter()
                .zip(&z)
                .map(|(a, b)| (a - b).abs() / (1.0 + a.abs()))
                .fold(0.0, f64::max);
            worst = worst.max(dev);
            if !ok || dev > 1e-8 {
                bad += 1;
            }
        }
        println!(
            "{name}: {samples} thetas, {bad} mismatches, {uncovered} uncovered, worst relative deviation {worst:.1e}"
        );
        let (t64, t32) = match &ctl.tables {
            AnyTables::Narrow(t) => (
                eval_time(&t.tables(), &thetas, k),
                eval_time(&t.cast::<f32>().tables(), &thetas, k),
            ),
            AnyTables::Wide(t) => (
                eval_time(&t.tables(), &thetas, k),
                eval_time(&t.cast::<f32>().tables(), &thetas, k),
            ),
        };
        println!(
            "{name}: evaluation {:.0} ns (f64), {:.0} ns (f32) per parameter (best of 3 passes over the {samples})",
            t64 * 1e9,
            t32 * 1e9
        );
    }
}
