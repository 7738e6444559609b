//! Explicit MPC: the mpQP solve of a 9-parameter, 8-variable problem with
//! about a thousand regions, and the tree evaluation of the thesis-sized
//! controller (9 parameters, 4 outputs) in f64, f32 and Q16, in the default and
//! the compact layout.

use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_core::{Q16, Scalar};
use kestrel_empc::mpqp::Rng;
use kestrel_empc::{
    Settings, TreeSettings, TreeTables, build_compact, build_controller, evaluate, solve, testing,
};
use std::hint::black_box;

fn solve_bench(c: &mut Criterion) {
    let prob = testing::benchmark_9x8();
    let sol = solve(&prob, &Settings::default()).unwrap();
    eprintln!(
        "benchmark_9x8: {} parameters, {} variables, {} regions, solve_seconds {:.4}",
        prob.p(),
        prob.n(),
        sol.regions.len(),
        sol.stats.solve_seconds
    );
    let mut g = c.benchmark_group("empc solve 9x8");
    g.sample_size(10);
    g.bench_function("parallel", |b| {
        b.iter(|| solve(black_box(&prob), &Settings::default()).unwrap())
    });
    let seq = Settings {
        parallel: false,
        ..Settings::default()
    };
    g.bench_function("sequential", |b| {
        b.iter(|| solve(black_box(&prob), &seq).unwrap())
    });
    g.finish();
}

fn eval_one<S: Scalar, T: TreeTables<S>>(c: &mut Criterion, name: &str, t: &T, thetas: &[[S; 9]]) {
    let mut z = [S::ZERO; 4];
    let mut i = 0;
    c.bench_function(&format!("empc eval thesis-sized {name}"), |b| {
        b.iter(|| {
            i = (i + 1) % thetas.len();
            evaluate(black_box(t), black_box(&thetas[i]), &mut z).unwrap();
            black_box(z)
        })
    });
}

fn eval_bench(c: &mut Criterion) {
    let prob = testing::thesis_sized(1);
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    eprintln!(
        "thesis-sized: {} regions, {} laws, depth {}, {} nodes, {} bytes (f32)",
        sol.regions.len(),
        ctl.stats.distinct_laws,
        ctl.stats.depth,
        ctl.stats.nodes,
        ctl.tables.bytes(4)
    );
    let mut rng = Rng::new(3);
    let thetas: Vec<[f64; 9]> = (0..1024)
        .map(|_| {
            core::array::from_fn(|j| {
                let (lo, hi) = (prob.theta_lb[j], prob.theta_ub[j]);
                lo + (hi - lo) * 0.5 * (rng.sym() + 1.0)
            })
        })
        .collect();
    let cast =
        |th: &[[f64; 9]]| -> Vec<[f32; 9]> { th.iter().map(|t| t.map(|v| v as f32)).collect() };
    eval_one(c, "f64", &ctl.tables.tables(), &thetas);
    let t32 = ctl.tables.cast::<f32>();
    eval_one(c, "f32", &t32.tables(), &cast(&thetas));
    let tq = ctl.tables.cast::<Q16>();
    let thq: Vec<[Q16; 9]> = thetas.iter().map(|t| t.map(Q16::from_f64)).collect();
    eval_one(c, "q16", &tq.tables(), &thq);
    // The compact layout (one tree per output) of the same controller.
    let compact = build_compact(&prob, &sol, &TreeSettings::default()).unwrap();
    eprintln!(
        "thesis-sized compact: depth {}, {} nodes, {} bytes (f32)",
        compact.depth,
        compact.tables.nodes.len(),
        compact.tables.bytes(4)
    );
    eval_one(c, "compact f64", &compact.tables.tables(), &thetas);
    let c32 = compact.tables.cast::<f32>();
    eval_one(c, "compact f32", &c32.tables(), &cast(&thetas));
}

criterion_group!(benches, solve_bench, eval_bench);
criterion_main!(benches);
