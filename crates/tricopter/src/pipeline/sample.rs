//! Points of a parameter box for the pipeline's checks against the
//! reference QP, from a seeded SplitMix64 sequence (the check points of
//! the report depend on it), and the QP objective.

use kestrel_core::formats::MpqpProblem;
use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// A seeded generator of parameter points: the workspace's seeded
/// generator `rand_xoshiro::SplitMix64` (the seed is its state), one
/// uniform `[0, 1)` deviate (`random::<f64>()`, the top 53 bits over
/// `2^53`) per coordinate.
#[derive(Clone, Debug)]
pub struct BoxSampler(SplitMix64);

impl BoxSampler {
    /// A sampler from a seed.
    pub fn new(seed: u64) -> Self {
        BoxSampler(SplitMix64::seed_from_u64(seed))
    }

    /// A point of the problem's parameter box.
    pub fn theta(&mut self, p: &MpqpProblem) -> DVector<f64> {
        DVector::from_fn(p.p(), |i, _| {
            p.theta_lb[i] + (p.theta_ub[i] - p.theta_lb[i]) * self.0.random::<f64>()
        })
    }
}

/// `1/2 z'Hz + (F'theta + f)'z`, the QP's objective, evaluated directly.
pub fn qp_cost(p: &MpqpProblem, z: &DVector<f64>, theta: &DVector<f64>) -> f64 {
    0.5 * z.dot(&(&p.h * z)) + p.linear_term(theta).dot(z)
}
