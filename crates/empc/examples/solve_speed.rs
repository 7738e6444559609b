//! CPU time of the sequential mpQP solve of `testing::benchmark_9x8` (the
//! machine is shared, so wall time alone misleads):
//! `cargo run --release -p kestrel-empc --example solve_speed [repeats]`.
//!
//! `... --example solve_speed -- --regions [problem.json ...]` instead
//! prints, for the benchmark, the thesis-sized test problems (seeds 1 to 6),
//! two move-blocked problems and the given problem files, the region count
//! and a fingerprint of the set of active sets (order-independent), to
//! check that a change of the solver finds the same regions.
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::{Settings, solve, testing};

/// User + system CPU seconds of this process (Linux `/proc/self/stat`, 100 Hz ticks).
fn cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = s.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

/// FNV-1a over the sorted list of sorted active sets.
fn fingerprint(sets: &mut [Vec<usize>]) -> u64 {
    for s in sets.iter_mut() {
        s.sort_unstable();
    }
    sets.sort();
    let mut h = 0xCBF2_9CE4_8422_2325u64;
    for s in sets.iter() {
        for &i in s.iter().chain([&usize::MAX]) {
            h = (h ^ i as u64).wrapping_mul(0x0100_0000_01B3);
        }
    }
    h
}

fn regions(extra: &[String]) {
    let mut probs: Vec<(String, MpqpProblem)> =
        vec![("benchmark_9x8".into(), testing::benchmark_9x8())];
    for seed in 1..=6 {
        probs.push((format!("thesis_sized({seed})"), testing::thesis_sized(seed)));
    }
    for (seed, ns) in [(11u64, 2usize), (12, 3)] {
        let mut s = testing::random_system(4, 2, 2, 0.9, seed);
        s.horizon = 5;
        s.free_moves = ns;
        s.throttle_inputs = vec![0];
        s.throttle_range = (-0.3, 0.3);
        probs.push((
            format!("blocked(4x2, N 5, Ns {ns}, seed {seed})"),
            s.condense(),
        ));
    }
    for path in extra {
        let p = MpqpProblem::read(std::path::Path::new(path)).expect("problem file");
        probs.push((path.clone(), p));
    }
    let settings = Settings {
        parallel: false,
        ..Settings::default()
    };
    for (name, prob) in &probs {
        let c0 = cpu_seconds();
        let sol = solve(prob, &settings).expect("solve");
        let mut sets: Vec<Vec<usize>> = sol.regions.iter().map(|r| r.active_set.clone()).collect();
        // The regions' numbers (half-spaces, ball, law), bit for bit, in the
        // order of their sorted active sets.
        let mut order: Vec<usize> = (0..sol.regions.len()).collect();
        let key = |i: usize| {
            let mut s = sol.regions[i].active_set.clone();
            s.sort_unstable();
            s
        };
        order.sort_by_key(|&i| key(i));
        let mut h = 0xCBF2_9CE4_8422_2325u64;
        for &i in &order {
            let r = &sol.regions[i];
            let nums = r.a.iter().chain(r.b.iter()).chain(r.center.iter());
            let nums = nums
                .chain([&r.radius])
                .chain(r.fz.iter())
                .chain(r.gz.iter());
            for v in nums {
                h = (h ^ v.to_bits()).wrapping_mul(0x0100_0000_01B3);
            }
        }
        println!(
            "{name}: {} regions, active sets {:016x}, numbers {h:016x}, {} LPs, {} fallback QPs, CPU {:.3} s",
            sol.regions.len(),
            fingerprint(&mut sets),
            sol.stats.lps,
            sol.stats.fallback_qps,
            cpu_seconds() - c0
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--regions") {
        regions(&args[1..]);
        return;
    }
    let repeats: usize = args.first().and_then(|v| v.parse().ok()).unwrap_or(10);
    let prob = testing::benchmark_9x8();
    let settings = Settings {
        parallel: false,
        ..Settings::default()
    };
    let c0 = cpu_seconds();
    let w0 = std::time::Instant::now();
    let mut last = None;
    for _ in 0..repeats {
        last = Some(solve(&prob, &settings).expect("solve"));
    }
    let cpu = (cpu_seconds() - c0) / repeats as f64;
    let wall = w0.elapsed().as_secs_f64() / repeats as f64;
    let sol = last.expect("at least one repeat");
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "benchmark_9x8 sequential: {} regions, {} LPs, {} fallback QPs, {} sets tested; CPU {cpu:.4} s, wall {wall:.4} s per solve ({repeats} repeats); load {}",
        sol.regions.len(),
        sol.stats.lps,
        sol.stats.fallback_qps,
        sol.stats.active_sets_tested,
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
}
