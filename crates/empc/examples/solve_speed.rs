//! CPU time of the sequential mpQP solve of `testing::benchmark_9x8` (the
//! machine is shared, so wall time alone misleads):
//! `cargo run --release -p kestrel-empc --example solve_speed [repeats]`.
use kestrel_empc::{Settings, solve, testing};

/// User + system CPU seconds of this process (Linux `/proc/self/stat`, 100 Hz ticks).
fn cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = s.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
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
