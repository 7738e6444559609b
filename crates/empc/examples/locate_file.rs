//! Solves an mpQP and builds the candidate-list point location of its
//! first move, then checks it against the solution's region lookup and
//! times its evaluation (the figures of docs/empc-point-location.md):
//! `cargo run --release -p kestrel-empc --features parallel --example
//! locate_file -- PROBLEM.json [first_move] [samples] [leaf_regions]
//! [shrink] [tries]` (a `kestrel.mpqp.v1` file).
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::locate::{LocateSettings, Progress, build_lists, estimate};
use kestrel_empc::{ListSlices, Outputs, Settings, evaluate_lists, solve};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;
use std::time::Instant;

fn problem(arg: &str) -> MpqpProblem {
    MpqpProblem::read(std::path::Path::new(arg)).expect("problem file")
}

/// Mean seconds per call of `evaluate_lists` over `thetas`.
fn time_eval<S: kestrel_core::Scalar, I: kestrel_empc::TreeIndex>(
    t: &ListSlices<'_, S, I>,
    thetas: &[Vec<f64>],
    k: usize,
) -> f64 {
    let ts: Vec<Vec<S>> = thetas
        .iter()
        .map(|th| th.iter().map(|&v| S::from_f64(v)).collect())
        .collect();
    let mut scratch = vec![S::ZERO; t.n_params];
    let mut z = vec![S::ZERO; k];
    let reps = 20;
    let start = Instant::now();
    let mut sink = 0usize;
    for _ in 0..reps {
        for th in &ts {
            let e =
                evaluate_lists(t, std::hint::black_box(th), &mut scratch, &mut z).expect("eval");
            sink = sink.wrapping_add(e.law.index());
        }
    }
    std::hint::black_box(sink);
    start.elapsed().as_secs_f64() / (reps * ts.len()) as f64
}

fn main() {
    let mut args = std::env::args().skip(1);
    let prob = problem(&args.next().expect("a problem"));
    let k: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(4);
    let samples: usize = args.next().and_then(|v| v.parse().ok()).unwrap_or(10_000);
    let defaults = LocateSettings::default();
    let leaf: usize = args
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or(defaults.leaf_regions);
    let shrink: f64 = args
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or(defaults.shrink);
    let tries: usize = args
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or(defaults.tries);
    let t0 = Instant::now();
    let sol = solve(&prob, &Settings::default()).expect("solve");
    let solve_s = t0.elapsed().as_secs_f64();
    println!(
        "p {} n {} m {}: {} regions, solve {:.3} s wall",
        prob.p(),
        prob.n(),
        prob.m(),
        sol.regions.len(),
        solve_s
    );
    let settings = LocateSettings {
        outputs: Outputs::First(k),
        leaf_regions: leaf,
        shrink,
        tries,
        ..defaults
    };
    let t1 = Instant::now();
    let est = estimate(&prob, &sol, &settings).expect("estimate");
    println!("estimate ({:.3} s): {est:?}", t1.elapsed().as_secs_f64());
    let t2 = Instant::now();
    let mut last = None;
    let c = build_lists(&prob, &sol, &settings, &mut |p: Progress| {
        if last != Some(p.stage) {
            eprintln!("  {:?} at {:.2} s", p.stage, t2.elapsed().as_secs_f64());
            last = Some(p.stage);
        }
    })
    .expect("lists");
    let build_s = t2.elapsed().as_secs_f64();
    println!("lists ({build_s:.3} s): {:?}", c.stats);
    println!(
        "solve + locate {:.3} s wall; bytes f32 {} (u16: {})",
        solve_s + build_s,
        c.stats.bytes_f32,
        c.stats.fits_u16
    );
    // Exactness against the region lookup, at random parameters in the box.
    let mut rng = SplitMix64::seed_from_u64(1);
    let p = sol.p;
    let thetas: Vec<Vec<f64>> = (0..samples)
        .map(|_| {
            (0..p)
                .map(|j| {
                    let (lo, hi) = (sol.theta_lb[j], sol.theta_ub[j]);
                    lo + (hi - lo) * rng.random::<f64>()
                })
                .collect()
        })
        .collect();
    let (mut inside, mut bad, mut worst) = (0, 0, 0.0_f64);
    let mut z = vec![0.0; k];
    for th in &thetas {
        c.tables.evaluate_f64(th, &mut z).expect("eval");
        if let Some(want) = sol.first_outputs_at(th, k) {
            inside += 1;
            let d = z
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs() / (1.0 + b.abs()))
                .fold(0.0, f64::max);
            worst = worst.max(d);
            if d > 1e-8 {
                bad += 1;
            }
        }
    }
    println!("exactness: {inside} of {samples} inside, {bad} mismatches, worst {worst:.2e}");
    let (f64_s, f32_s, width) = match c.tables.narrow() {
        Some(n) => (
            time_eval(&n.tables(), &thetas, k),
            time_eval(&n.cast::<f32>().tables(), &thetas, k),
            "u16",
        ),
        None => (
            time_eval(&c.tables.tables(), &thetas, k),
            time_eval(&c.tables.cast::<f32>().tables(), &thetas, k),
            "u32",
        ),
    };
    println!(
        "eval ({width} tables, mean of {}): f64 {:.3} us, f32 {:.3} us",
        20 * thetas.len(),
        f64_s * 1e6,
        f32_s * 1e6
    );
}
