//! Reproducible synthetic systems and data for tests, examples and benchmarks.

use crate::data::IoData;
use crate::error::Result;
use crate::linalg::spectral_radius;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};
use rand::{Rng as _, RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// A small deterministic random generator with normal samples: the
/// workspace's seeded generator, `rand_xoshiro::SplitMix64`.
#[derive(Clone, Debug)]
pub struct Rng(SplitMix64);

impl Rng {
    /// A generator from a seed (the SplitMix64 state is
    /// `seed ^ 0x9E37_79B9_7F4A_7C15`).
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::seed_from_u64(seed ^ 0x9E37_79B9_7F4A_7C15))
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in `[0, 1)` (the top 53 bits of [`Rng::next_u64`] over `2^53`).
    pub fn uniform(&mut self) -> f64 {
        self.0.random::<f64>()
    }
    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
    /// A matrix of standard normal entries.
    pub fn normal_matrix(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.normal())
    }
}

/// A random stable innovation model of order `n` with `nu` inputs and
/// `ny` outputs: `A` has spectral radius exactly `radius` (< 1), `B`, `C`
/// are standard normal, `D = 0`, and `K` is random and scaled so that
/// `A - K C` has spectral radius at most `radius` too.
pub fn random_model(n: usize, nu: usize, ny: usize, seed: u64, radius: f64) -> InnovationModel {
    let mut rng = Rng::new(seed);
    let m = rng.normal_matrix(n, n);
    let rho = spectral_radius(&m).max(1e-12);
    let a = m * (radius / rho);
    let b = rng.normal_matrix(n, nu);
    let c = rng.normal_matrix(ny, n);
    let mut k = rng.normal_matrix(n, ny) * 0.2;
    for _ in 0..100 {
        if spectral_radius(&(&a - &k * &c)) <= radius {
            break;
        }
        k *= 0.8;
    }
    InnovationModel {
        ts: 1.0,
        a,
        b,
        c,
        d: DMatrix::zeros(ny, nu),
        k,
    }
}

/// Simulates the innovation model with white standard normal inputs and
/// white normal innovations of standard deviation `noise`, from a zero
/// state, after a burn-in of 200 samples that is dropped.
pub fn simulate(
    model: &InnovationModel,
    n_samples: usize,
    noise: f64,
    seed: u64,
) -> Result<IoData> {
    let mut rng = Rng::new(seed.wrapping_mul(7919).wrapping_add(1));
    let burn = 200;
    let total = n_samples + burn;
    let u = rng.normal_matrix(total, model.nu());
    let e = rng.normal_matrix(total, model.ny()) * noise;
    let y = simulate_innovation(model, &u, &e, &DVector::zeros(model.nx()))?;
    IoData::new(
        model.ts,
        u.rows(burn, n_samples).into_owned(),
        y.rows(burn, n_samples).into_owned(),
    )
}

/// Output of the innovation model for given inputs `u` (`N x nu`) and
/// innovations `e` (`N x ny`) from state `x0`.
pub fn simulate_innovation(
    model: &InnovationModel,
    u: &DMatrix<f64>,
    e: &DMatrix<f64>,
    x0: &DVector<f64>,
) -> Result<DMatrix<f64>> {
    model.check_io(u, Some(e), x0)?;
    let mut x = x0.clone();
    let mut y = DMatrix::zeros(u.nrows(), model.ny());
    for t in 0..u.nrows() {
        let ut = u.row(t).transpose();
        let et = e.row(t).transpose();
        let yt = &model.c * &x + &model.d * &ut + &et;
        y.row_mut(t).copy_from(&yt.transpose());
        x = &model.a * &x + &model.b * &ut + &model.k * &et;
    }
    Ok(y)
}
