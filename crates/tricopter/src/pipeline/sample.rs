//! Points of a parameter box for the pipeline's checks against the
//! reference QP, from a seeded SplitMix64 sequence (the check points of
//! the report depend on it), and the QP objective.

use kestrel_core::formats::MpqpProblem;
use nalgebra::DVector;

/// A seeded generator of parameter points (SplitMix64).
#[derive(Clone, Debug)]
pub struct BoxSampler(u64);

impl BoxSampler {
    /// A sampler from a seed.
    pub fn new(seed: u64) -> Self {
        BoxSampler(seed)
    }

    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A point of the problem's parameter box.
    pub fn theta(&mut self, p: &MpqpProblem) -> DVector<f64> {
        DVector::from_fn(p.p(), |i, _| {
            p.theta_lb[i] + (p.theta_ub[i] - p.theta_lb[i]) * self.uniform()
        })
    }
}

/// `1/2 z'Hz + (F'theta + f)'z`, the QP's objective, evaluated directly.
pub fn qp_cost(p: &MpqpProblem, z: &DVector<f64>, theta: &DVector<f64>) -> f64 {
    0.5 * z.dot(&(&p.h * z)) + p.linear_term(theta).dot(z)
}
