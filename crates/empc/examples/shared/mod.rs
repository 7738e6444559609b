//! Helpers shared by the examples that measure trees: process CPU time
//! and host evaluation time of either table layout, the arguments of the
//! whole-box sweeps.
#![allow(dead_code)] // not every example uses every helper

use kestrel_core::Scalar;
use kestrel_empc::eval::{TreeIndex, TreeTables};
use kestrel_empc::evaluate_with;
use kestrel_empc::tree::{AnyTables, OwnedTables};

/// CPU seconds of this process (user + system), from `/proc/self/stat`.
pub fn cpu_seconds() -> f64 {
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

/// The arguments `problem.json [first_move] [samples] [every]` the
/// whole-box sweeps start with (`whole_box`, `clarabel_check`).
pub struct SweepArgs {
    /// The problem file.
    pub path: String,
    /// Outputs kept (default 4: the first move).
    pub first_move: usize,
    /// Random parameters in the box (default 10^4).
    pub samples: usize,
    /// Every how many of them clarabel is compared (default 50).
    pub every: usize,
}

impl SweepArgs {
    /// The first four arguments of `args` (the rest are left there).
    pub fn read(args: &mut impl Iterator<Item = String>) -> SweepArgs {
        let path = args.next().expect("a problem file");
        let mut number = |default| args.next().and_then(|v| v.parse().ok()).unwrap_or(default);
        SweepArgs {
            path,
            first_move: number(4),
            samples: number(10_000),
            every: number(50),
        }
    }
}

/// The parameters in scalar `S`.
pub fn in_scalar<S: Scalar>(thetas: &[Vec<f64>]) -> Vec<Vec<S>> {
    thetas
        .iter()
        .map(|th| th.iter().map(|&v| S::from_f64(v)).collect())
        .collect()
}

/// Mean seconds per evaluation of `tables` over `thetas` (best of three passes).
pub fn eval_time<S: Scalar, I: TreeIndex, T: TreeTables<S, I>>(
    tables: &T,
    thetas: &[Vec<f64>],
) -> f64 {
    let ths: Vec<Vec<S>> = in_scalar(thetas);
    let mut z = vec![S::ZERO; tables.n_outputs()];
    let mut scratch = vec![S::ZERO; tables.n_params()];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let w = std::time::Instant::now();
        for th in &ths {
            let e = evaluate_with(tables, std::hint::black_box(th), &mut scratch, &mut z);
            std::hint::black_box((&e, &z));
        }
        best = best.min(w.elapsed().as_secs_f64() / ths.len().max(1) as f64);
    }
    best
}

/// [`eval_time`] of the tables in f64 and in f32, either layout.
pub fn eval_times(tables: &AnyTables, thetas: &[Vec<f64>]) -> (f64, f64) {
    fn both<X: TreeIndex>(t: &OwnedTables<f64, X>, thetas: &[Vec<f64>]) -> (f64, f64) {
        (
            eval_time(&t.tables(), thetas),
            eval_time(&t.cast::<f32>().tables(), thetas),
        )
    }
    match tables {
        AnyTables::Narrow(t) => both(t, thetas),
        AnyTables::Wide(t) => both(t, thetas),
    }
}
