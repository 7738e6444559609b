//! Explicit MPC: the mpQP solve of a 9-parameter, 8-variable problem with
//! about a thousand regions, and the tree evaluation of the thesis-sized
//! controller (9 parameters, 4 outputs) in f64, f32 and Q16, in the default,
//! the wide (u32) and the compact layout. The group `empc solve 9x8 cpu`
//! measures the sequential solve in CPU time of the benchmarking thread
//! (Linux; its tick-based resolution is too coarse for one evaluation:
//! kestrel-empc's `eval_file` example times trees in CPU time over long
//! passes). The group `empc solve 9x8 cpu` measures the sequential
//! solve in CPU time of the benchmarking thread (Linux), which a loaded
//! machine inflates far less than wall time.

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kestrel_core::{Q16, Scalar};
use kestrel_empc::eval::TreeIndex;
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

fn eval_one<S: Scalar, I: TreeIndex, T: TreeTables<S, I>>(
    c: &mut Criterion,
    name: &str,
    t: &T,
    thetas: &[[S; 9]],
) {
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
    // The same tree in the wide (u32) layout, what trees beyond 32767 nodes get.
    let w = ctl.tables.widen();
    eval_one(c, "wide f64", &w.tables(), &thetas);
    let w32 = w.cast::<f32>();
    eval_one(c, "wide f32", &w32.tables(), &cast(&thetas));
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

/// CPU time of the calling thread in nanoseconds (Linux
/// `/proc/thread-self/schedstat`, first field): the machine is shared, so
/// wall time grows with the load while the CPU time of a sequential solve
/// does not (much).
fn thread_cpu_ns() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(0.0)
}

/// A criterion measurement of thread CPU time (for single-threaded code).
struct CpuTime;

/// Formats nanoseconds of CPU time like criterion's wall time.
struct CpuFormatter;

impl ValueFormatter for CpuFormatter {
    fn scale_values(&self, typical: f64, values: &mut [f64]) -> &'static str {
        let (factor, unit) = if typical < 1e3 {
            (1.0, "ns cpu")
        } else if typical < 1e6 {
            (1e-3, "us cpu")
        } else if typical < 1e9 {
            (1e-6, "ms cpu")
        } else {
            (1e-9, "s cpu")
        };
        values.iter_mut().for_each(|v| *v *= factor);
        unit
    }
    fn scale_throughputs(
        &self,
        _typical: f64,
        _t: &Throughput,
        values: &mut [f64],
    ) -> &'static str {
        // Not used: elements per CPU second.
        values.iter_mut().for_each(|v| *v = 1e9 / *v);
        "elem/s cpu"
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}

impl Measurement for CpuTime {
    type Intermediate = f64;
    type Value = f64;
    fn start(&self) -> f64 {
        thread_cpu_ns()
    }
    fn end(&self, start: f64) -> f64 {
        thread_cpu_ns() - start
    }
    fn add(&self, a: &f64, b: &f64) -> f64 {
        a + b
    }
    fn zero(&self) -> f64 {
        0.0
    }
    fn to_f64(&self, v: &f64) -> f64 {
        *v
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &CpuFormatter
    }
}

/// The sequential solve of the 9x8 problem measured in CPU time of the
/// benchmarking thread (the figure to compare across machine loads).
fn solve_cpu_bench(c: &mut Criterion<CpuTime>) {
    let prob = testing::benchmark_9x8();
    let seq = Settings {
        parallel: false,
        ..Settings::default()
    };
    let mut g = c.benchmark_group("empc solve 9x8 cpu");
    g.sample_size(10);
    g.bench_function("sequential", |b| {
        b.iter(|| solve(black_box(&prob), &seq).unwrap())
    });
    g.finish();
}

criterion_group!(benches, solve_bench, eval_bench);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime);
    targets = solve_cpu_bench
}
criterion_main!(benches, cpu);
