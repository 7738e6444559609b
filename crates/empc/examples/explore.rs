//! Scratch: region counts and timings of the test problems.
use kestrel_empc::{Settings, brute_force_active_sets, solve, testing};
fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    let mut probs = vec![];
    if which.is_empty() || which == "small" {
        for seed in 0..3 {
            let mut s = testing::random_system(2, 1, 0, 0.9, seed);
            s.horizon = 4;
            s.free_moves = 2;
            probs.push((format!("di-like seed {seed}"), s.condense(), true));
        }
        probs.push(("thesis".into(), testing::thesis_sized(1), true));
    }
    if which.is_empty() || which == "big" {
        probs.push(("bench".into(), testing::benchmark_9x8(), false));
    }
    for (name, p, brute) in probs {
        let t = std::time::Instant::now();
        let sol = solve(&p, &Settings::default()).unwrap();
        let dt = t.elapsed().as_secs_f64();
        println!(
            "{name}: n={} p={} m={} regions={} {:?} {dt:.4}s",
            p.n(),
            p.p(),
            p.m(),
            sol.regions.len(),
            sol.stats
        );
        if brute {
            let bf = brute_force_active_sets(&p, &Settings::default()).unwrap();
            let mut ex: Vec<Vec<usize>> =
                sol.regions.iter().map(|r| r.active_set.clone()).collect();
            ex.sort();
            println!(
                "  brute force {} explorer {} equal {}",
                bf.len(),
                ex.len(),
                bf == ex
            );
        }
    }
}
