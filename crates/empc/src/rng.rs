//! The crate's seeded generator (SplitMix64): probe perturbations of the
//! mpQP exploration and the random test problems of [`crate::testing`].
//!
//! A leaf module: it uses nothing else of the crate. The sequence is fixed
//! (the golden files under `tests/` depend on it).

/// A small deterministic random generator (SplitMix64), used for probe
/// perturbations and by the test problems.
#[derive(Clone, Debug)]
pub struct Rng(u64);
impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [-1, 1).
    pub fn sym(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}
