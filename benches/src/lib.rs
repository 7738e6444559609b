//! Criterion benchmarks across the kestrel crates live in `benches/`; run
//! them with `cargo bench -p kestrel-benches`. This library only holds
//! shared problem generators.

/// A deterministic pseudo-random sequence in `[-1, 1)` (xorshift), so
/// benchmarks use the same data on every run without a dependency.
pub fn pseudo_random(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.max(1);
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
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
