//! CPU time per `dare` call on the problems of `benches/benches/kalman.rs`
//! (the same sequence), comparable with the CPU time that
//! `crates/kalman/scripts/scipy_dare.py` reports for SciPy. CPU time of
//! this thread (`/proc/thread-self/schedstat`), best of 3 runs of
//! thousands of calls, so neither other processes on a loaded machine nor
//! the scheduler tick distort it. Linux only (prints 0 elsewhere).
//!
//! ```sh
//! cargo run --release -p kestrel-kalman --example dare_cpu_time [n]
//! ```
use kestrel_kalman::dare;
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// `n` numbers uniform in `[-1, 1)` from the workspace's seeded generator
/// (`rand_xoshiro::SplitMix64`): the sequence of
/// `kestrel_benches::pseudo_random` and of `scipy_dare.py`.
fn pseudo_random(seed: u64, n: usize) -> Vec<f64> {
    let mut rng = SplitMix64::seed_from_u64(seed);
    (0..n).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect()
}

fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(0)
}

fn main() {
    let only: Option<usize> = std::env::args().nth(1).and_then(|s| s.parse().ok());
    for n in [5usize, 20, 60] {
        if only.is_some_and(|o| o != n) {
            continue;
        }
        let m = 1 + n / 4;
        let p = 1 + n / 3;
        let scale = 1.1 * 3f64.sqrt() / (n as f64).sqrt();
        let a = DMatrix::from_row_slice(n, n, &pseudo_random(11 + n as u64, n * n)) * scale;
        let b = DMatrix::from_row_slice(n, m, &pseudo_random(23 + n as u64, n * m));
        let c = DMatrix::from_row_slice(p, n, &pseudo_random(37 + n as u64, p * n));
        let q = c.transpose() * c;
        let r = DMatrix::identity(m, m);
        let sol = dare(&a, &b, &q, &r, None).unwrap();
        let reps = if n == 60 {
            200
        } else if n == 20 {
            3000
        } else {
            20000
        };
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = thread_cpu_ns();
            for _ in 0..reps {
                std::hint::black_box(dare(&a, &b, &q, &r, None).unwrap());
            }
            best = best.min((thread_cpu_ns() - t) as f64 / reps as f64);
        }
        println!(
            "n={n}: {:.1} us cpu, {} it, {} ref, res {:.1e}",
            best / 1e3,
            sol.iterations,
            sol.refinements,
            sol.residual
        );
    }
}
