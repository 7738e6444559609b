//! The crate's seeded generator (`rand_xoshiro::SplitMix64`): probe
//! perturbations of the mpQP exploration and the random test problems of
//! [`crate::testing`].
//!
//! A leaf module: it uses nothing else of the crate. The sequence is fixed
//! (the golden files under `tests/` depend on it).

use rand::{Rng as _, RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// A small deterministic random generator (`rand_xoshiro::SplitMix64`, the
/// workspace's seeded generator), used for probe perturbations and by the
/// test problems.
#[derive(Clone, Debug)]
pub struct Rng(SplitMix64);
impl Rng {
    /// A generator from a seed (the SplitMix64 state is
    /// `seed ^ 0x9E37_79B9_7F4A_7C15`).
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::seed_from_u64(seed ^ 0x9E37_79B9_7F4A_7C15))
    }
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in [-1, 1).
    pub fn sym(&mut self) -> f64 {
        self.0.random::<f64>() * 2.0 - 1.0
    }
}
