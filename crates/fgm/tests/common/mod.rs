//! Condensed MPC test problems built here (kestrel-mpc builds the thesis
//! ones; these are independent of it): a random stable system, an input
//! box that moves with a throttle parameter, and a random-theta sampler.
#![allow(dead_code)]

use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};
use rand::{Rng as _, RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// The workspace's seeded generator, `rand_xoshiro::SplitMix64` (the
/// seed is its state), with the draws the tests use.
pub struct Rng(SplitMix64);
impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::seed_from_u64(seed))
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in `[lo, hi)`: `lo + (hi - lo) u` with `u = random::<f64>()`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.0.random::<f64>()
    }
}

/// A condensed MPC problem: `nx` states, `nu` inputs, horizon `n_h`,
/// theta = [x0; throttle]. Inputs 0 .. nu-1 except the last obey
/// `lo_pwm - throttle <= u <= hi_pwm - throttle` (thesis 6.5a, in PWM
/// microseconds), the last `-300 <= u <= 300` (6.5b).
pub fn mpc_problem(seed: u64, nx: usize, nu: usize, n_h: usize) -> MpqpProblem {
    let mut rng = Rng::new(seed);
    let a0 = DMatrix::from_fn(nx, nx, |_, _| rng.uniform(-1.0, 1.0));
    let norm = a0.clone().svd(false, false).singular_values.max();
    let a = a0 * (0.95 / norm);
    // Input gains of the order of the thesis's (rates per microsecond).
    let b = DMatrix::from_fn(nx, nu, |_, _| rng.uniform(-1.0, 1.0) * 1e-3);
    let q = DMatrix::from_diagonal(&DVector::from_fn(nx, |_, _| rng.uniform(50.0, 500.0)));
    let r = DMatrix::from_diagonal(&DVector::from_fn(nu, |_, _| rng.uniform(1e-4, 1e-3)));
    let n = nu * n_h;
    // X = Sx x0 + Su U over steps 1..=N.
    let mut sx = DMatrix::zeros(nx * n_h, nx);
    let mut su = DMatrix::zeros(nx * n_h, n);
    let mut ak = DMatrix::identity(nx, nx);
    for k in 0..n_h {
        ak = &a * &ak;
        sx.view_mut((k * nx, 0), (nx, nx)).copy_from(&ak);
        for j in 0..=k {
            let mut blk = b.clone();
            for _ in 0..(k - j) {
                blk = &a * blk;
            }
            su.view_mut((k * nx, j * nu), (nx, nu)).copy_from(&blk);
        }
    }
    let mut qbar = DMatrix::zeros(nx * n_h, nx * n_h);
    let mut rbar = DMatrix::zeros(n, n);
    for k in 0..n_h {
        qbar.view_mut((k * nx, k * nx), (nx, nx)).copy_from(&q);
        rbar.view_mut((k * nu, k * nu), (nu, nu)).copy_from(&r);
    }
    let h = su.transpose() * &qbar * &su + rbar;
    let h = (&h + h.transpose()) * 0.5;
    let p = nx + 1;
    let mut f_theta = DMatrix::zeros(p, n);
    let fx = sx.transpose() * &qbar * &su; // nx x n
    f_theta.view_mut((0, 0), (nx, n)).copy_from(&fx);
    // Shuffle and scale the box rows to exercise the conversion.
    let mut rows: Vec<(Vec<f64>, f64, Vec<f64>)> = Vec::new();
    for k in 0..n_h {
        for i in 0..nu {
            let j = k * nu + i;
            let s = rng.uniform(0.5, 3.0);
            let mut gu = vec![0.0; n];
            let mut gl = vec![0.0; n];
            gu[j] = s;
            gl[j] = -s;
            let mut eu = vec![0.0; p];
            let mut el = vec![0.0; p];
            if i + 1 < nu {
                // s u <= s (2000 - th), -s u <= -s (1000 - th)
                eu[nx] = -s;
                el[nx] = s;
                rows.push((gu, 2000.0 * s, eu));
                rows.push((gl, -1000.0 * s, el));
            } else {
                rows.push((gu, 300.0 * s, eu));
                rows.push((gl, 300.0 * s, el));
            }
        }
    }
    for i in (1..rows.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        rows.swap(i, j);
    }
    let m = rows.len();
    let g = DMatrix::from_fn(m, n, |i, j| rows[i].0[j]);
    let w = DVector::from_fn(m, |i, _| rows[i].1);
    let e = DMatrix::from_fn(m, p, |i, j| rows[i].2[j]);
    let mut theta_lb = DVector::from_element(p, -0.5);
    let mut theta_ub = DVector::from_element(p, 0.5);
    theta_lb[nx] = 1100.0;
    theta_ub[nx] = 1900.0;
    MpqpProblem {
        h,
        f_theta,
        f: DVector::zeros(n),
        g,
        w,
        e,
        theta_lb,
        theta_ub,
        theta_poly: None,
    }
}

/// Uniform random theta in the parameter box.
pub fn random_theta(rng: &mut Rng, lb: &DVector<f64>, ub: &DVector<f64>) -> DVector<f64> {
    DVector::from_fn(lb.len(), |i, _| rng.uniform(lb[i], ub[i]))
}
