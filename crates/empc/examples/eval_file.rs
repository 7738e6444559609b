//! Host evaluation time of a solution file's tree (either layout), in CPU
//! time of this thread (the machine is shared: wall time grows with the
//! load, CPU time much less) and wall time:
//!
//! `cargo run --release -p kestrel-empc --example eval_file -- solution.json
//! [samples] [repeats]`
//!
//! `samples` (default 10^4) random parameters in the box, all evaluated
//! `repeats` times (default 50) in one timed run (f64 tables, then f32);
//! the mean per evaluation is reported. The thread's CPU time
//! (`/proc/thread-self/schedstat`) advances in scheduler ticks, so the run
//! is long (10^4 x 50 evaluations, a few hundred ms) to make that
//! granularity negligible. The solution file comes from `kestrel empc
//! solve` or the `whole_box` example.
#[path = "../tests/common/mod.rs"]
mod common;
mod shared;

use kestrel_core::Scalar;
use kestrel_empc::eval::{TreeIndex, TreeTables};
use kestrel_empc::evaluate_with;
use kestrel_empc::export::read_tables;
use kestrel_empc::tree::{AnyTables, OwnedTables};

/// CPU nanoseconds of this thread (`/proc/thread-self/schedstat`).
fn thread_cpu_ns() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(f64::NAN)
}

/// Mean (CPU, wall) nanoseconds per evaluation over `repeats` passes.
fn time<S: Scalar, I: TreeIndex, T: TreeTables<S, I>>(
    t: &T,
    thetas: &[Vec<f64>],
    repeats: usize,
) -> (f64, f64) {
    let ths: Vec<Vec<S>> = shared::in_scalar(thetas);
    let mut z = vec![S::ZERO; t.n_outputs()];
    let mut scratch = vec![S::ZERO; t.n_params()];
    let n = (ths.len() * repeats).max(1) as f64;
    let (c0, w0) = (thread_cpu_ns(), std::time::Instant::now());
    for _ in 0..repeats {
        for th in &ths {
            let e = evaluate_with(t, std::hint::black_box(th), &mut scratch, &mut z);
            std::hint::black_box((&e, &z));
        }
    }
    let wall = w0.elapsed().as_nanos() as f64 / n;
    ((thread_cpu_ns() - c0) / n, wall)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("a solution file");
    let samples: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(10_000);
    let passes: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(50);
    let text = std::fs::read_to_string(&path).expect("read the solution file");
    let tables: AnyTables = read_tables(&text).expect("tables");
    let thetas = match &tables {
        AnyTables::Narrow(t) => common::box_samples(&t.theta_lb, &t.theta_ub, samples, 7),
        AnyTables::Wide(t) => common::box_samples(&t.theta_lb, &t.theta_ub, samples, 7),
    };
    let ((c64, w64), (c32, w32), steps) = match &tables {
        AnyTables::Narrow(t) => measure(t, &thetas, passes),
        AnyTables::Wide(t) => measure(t, &thetas, passes),
    };
    println!(
        "{path}: {} layout, {} nodes, {} bytes (f32), mean path {steps:.1} nodes; per evaluation: f64 {c64:.0} ns CPU ({w64:.0} ns wall), f32 {c32:.0} ns CPU ({w32:.0} ns wall)",
        if tables.is_wide() { "u32" } else { "u16" },
        tables.n_nodes(),
        tables.bytes(4)
    );
}

/// [`time`] of the tables in f64 and f32, and the mean path length.
fn measure<X: TreeIndex>(
    t: &OwnedTables<f64, X>,
    thetas: &[Vec<f64>],
    passes: usize,
) -> ((f64, f64), (f64, f64), f64) {
    (
        time(&t.tables(), thetas, passes),
        time(&t.cast::<f32>().tables(), thetas, passes),
        mean_steps(&t.tables(), thetas),
    )
}

/// The mean number of nodes visited.
fn mean_steps<I: TreeIndex, T: TreeTables<f64, I>>(t: &T, thetas: &[Vec<f64>]) -> f64 {
    let mut z = vec![0.0; t.n_outputs()];
    let mut scratch = vec![0.0; t.n_params()];
    let total: f64 = thetas
        .iter()
        .filter_map(|th| evaluate_with(t, th, &mut scratch, &mut z).ok())
        .map(|e| f64::from(e.steps))
        .sum();
    total / thetas.len().max(1) as f64
}
