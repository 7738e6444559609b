//! Reproducible synthetic systems and data for tests, examples and benchmarks.

use crate::data::IoData;
use crate::error::Result;
use crate::linalg::spectral_radius;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};

/// A small deterministic random generator (SplitMix64) with normal samples.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
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
