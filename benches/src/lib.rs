//! Criterion benchmarks across the kestrel crates live in `benches/`; run
//! them with `cargo bench -p kestrel-benches`. This library only holds
//! shared problem generators.

use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// A deterministic pseudo-random sequence in `[-1, 1)` from the
/// workspace's seeded generator (`rand_xoshiro::SplitMix64` with state
/// `seed`, mapped as `random::<f64>() * 2.0 - 1.0`), so benchmarks use the
/// same data on every run. `crates/kalman/examples/dare_cpu_time.rs` and
/// `crates/kalman/scripts/scipy_dare.py` write out the same sequence.
pub fn pseudo_random(seed: u64, n: usize) -> Vec<f64> {
    let mut rng = SplitMix64::seed_from_u64(seed);
    (0..n).map(|_| rng.random::<f64>() * 2.0 - 1.0).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn pseudo_random_is_deterministic_and_in_range() {
        let a = super::pseudo_random(7, 1000);
        assert_eq!(a, super::pseudo_random(7, 1000));
        assert!(a.iter().all(|v| (-1.0..1.0).contains(v)));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        assert!(mean.abs() < 0.1);
    }
}
