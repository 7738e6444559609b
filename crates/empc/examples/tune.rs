//! Scratch: tune the benchmark problem.
use kestrel_empc::{Settings, solve, testing};
fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let (xb, seed, rho, r) = (args[0], args[1] as u64, args[2], args[3]);
    let mut s = testing::random_system(9, 2, 0, rho, seed);
    s.horizon = 6;
    s.free_moves = 4;
    s.r = r;
    s.x_bound = xb;
    let p = s.condense();
    let sol = solve(&p, &Settings::default()).unwrap();
    if std::env::var("BRUTE").is_ok() {
        brute(&p, &sol);
    }
    println!(
        "xb {xb} seed {seed}: regions={} {:?}",
        sol.regions.len(),
        sol.stats
    );
}
#[allow(dead_code)]
fn brute(p: &kestrel_core::formats::MpqpProblem, sol: &kestrel_empc::MpqpSolution) {
    let bf = kestrel_empc::brute_force_active_sets(p, &Settings::default()).unwrap();
    let mut ex: Vec<Vec<usize>> = sol.regions.iter().map(|r| r.active_set.clone()).collect();
    ex.sort();
    let missing: Vec<_> = bf.iter().filter(|s| !ex.contains(s)).collect();
    let extra: Vec<_> = ex.iter().filter(|s| !bf.contains(s)).collect();
    println!(
        "brute {} explorer {} missing {:?} extra {:?}",
        bf.len(),
        ex.len(),
        &missing[..missing.len().min(5)],
        &extra[..extra.len().min(5)]
    );
}
