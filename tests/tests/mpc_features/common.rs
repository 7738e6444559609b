//! What the tests share: the sample count, the seed offset, relative
//! differences.

/// Random parameters per combination (the count).
pub const SAMPLES: usize = 1000;

/// Offset of every seed: `MPC_FEATURES_SEED=k` explores other models,
/// settings and parameters (0, the default, is what CI runs).
pub fn seed_offset() -> u64 {
    std::env::var("MPC_FEATURES_SEED")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .unwrap_or(0)
        .wrapping_mul(100_003)
}

/// Relative difference against `1 + |b|`.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / (1.0 + b.abs())
}

/// The largest entrywise [`rel`] of two vectors.
pub fn rel_vec(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max(rel(*x, *y)))
}
