//! Test and benchmark problems: small condensed MPC problems in the thesis form.
//!
//! These are deliberately simple (a stable random system, output tracking
//! with a constant reference, box-bounded inputs, optional move blocking
//! and a throttle that shifts some input bounds, as in the thesis's (6.7))
//! so the solver can be tested and benchmarked without the `kestrel-mpc`
//! crate. The move-blocked constraints are written over the whole horizon
//! as in the thesis's (6.26b), which produces exactly coincident rows.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

pub use crate::rng::Rng;
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};

/// A tracking MPC problem to condense.
#[derive(Clone, Debug)]
pub struct MpcSpec {
    /// State matrix `nx x nx`.
    pub a: DMatrix<f64>,
    /// Input matrix `nx x nu`.
    pub b: DMatrix<f64>,
    /// Output matrix `ny x nx`; `ny = 0` means regulation of the state without references.
    pub c: DMatrix<f64>,
    /// Output (or state) weight, a scalar times identity.
    pub q: f64,
    /// Input weight, a scalar times identity.
    pub r: f64,
    /// Prediction horizon `N`.
    pub horizon: usize,
    /// Number of free moves `Ns` (the input is held after `Ns` steps).
    pub free_moves: usize,
    /// Input lower bounds (`nu`).
    pub u_lo: Vec<f64>,
    /// Input upper bounds (`nu`).
    pub u_hi: Vec<f64>,
    /// Inputs whose bounds are shifted by the throttle parameter (as in (6.7));
    /// empty: no throttle parameter.
    pub throttle_inputs: Vec<usize>,
    /// Range of the throttle parameter.
    pub throttle_range: (f64, f64),
    /// Symmetric bound of every state parameter.
    pub x_bound: f64,
    /// Symmetric bound of every reference parameter.
    pub ref_bound: f64,
}

/// A random stable system: `A` scaled to spectral norm `rho`, random `B`, `C`.
pub fn random_system(nx: usize, nu: usize, ny: usize, rho: f64, seed: u64) -> MpcSpec {
    let mut rng = Rng::new(seed);
    let mut a = DMatrix::from_fn(nx, nx, |_, _| rng.sym());
    let s = a.clone().svd(false, false).singular_values.max().max(1e-12);
    a *= rho / s;
    let b = DMatrix::from_fn(nx, nu, |_, _| rng.sym());
    let c = DMatrix::from_fn(ny, nx, |_, _| rng.sym());
    MpcSpec {
        a,
        b,
        c,
        q: 1.0,
        r: 0.1,
        horizon: 2,
        free_moves: 2,
        u_lo: vec![-1.0; nu],
        u_hi: vec![1.0; nu],
        throttle_inputs: Vec::new(),
        throttle_range: (0.0, 0.0),
        x_bound: 2.0,
        ref_bound: 1.0,
    }
}

impl MpcSpec {
    /// Condenses into `kestrel.mpqp.v1`: `theta = [x; r; throttle]`,
    /// `z` = the `Ns` free moves.
    pub fn condense(&self) -> MpqpProblem {
        let nx = self.a.nrows();
        let nu = self.b.ncols();
        let ny = self.c.nrows();
        let track = ny > 0;
        let (cm, nyy) = if track {
            (self.c.clone(), ny)
        } else {
            (DMatrix::identity(nx, nx), nx)
        };
        let n_hor = self.horizon.max(1);
        let ns = self.free_moves.clamp(1, n_hor);
        let has_th = !self.throttle_inputs.is_empty();
        let p = nx + if track { ny } else { 0 } + usize::from(has_th);
        let nz = ns * nu;
        // Omega: U (N*nu) = Omega z.
        let mut omega = DMatrix::zeros(n_hor * nu, nz);
        for k in 0..n_hor {
            let kk = k.min(ns - 1);
            for i in 0..nu {
                omega[(k * nu + i, kk * nu + i)] = 1.0;
            }
        }
        // Y = Phi x + Gamma U, rows j = 1..N.
        let mut phi = DMatrix::zeros(n_hor * nyy, nx);
        let mut gamma = DMatrix::zeros(n_hor * nyy, n_hor * nu);
        let mut apow = DMatrix::identity(nx, nx);
        let mut apows = vec![apow.clone()];
        for _ in 0..n_hor {
            apow = &self.a * &apow;
            apows.push(apow.clone());
        }
        for j in 1..=n_hor {
            phi.view_mut(((j - 1) * nyy, 0), (nyy, nx))
                .copy_from(&(&cm * &apows[j]));
            for i in 0..j {
                let blk = &cm * &apows[j - 1 - i] * &self.b;
                gamma
                    .view_mut(((j - 1) * nyy, i * nu), (nyy, nu))
                    .copy_from(&blk);
            }
        }
        let gz = &gamma * &omega;
        let h = self.q * gz.transpose() * &gz + self.r * omega.transpose() * &omega;
        let h = 0.5 * (&h + h.transpose());
        // Linear term z'(q Gz'(Phi x - S r)) = theta' F z.
        let mut f_theta = DMatrix::zeros(p, nz);
        let fx = self.q * phi.transpose() * &gz; // nx x nz
        f_theta.view_mut((0, 0), (nx, nz)).copy_from(&fx);
        if track {
            let mut s = DMatrix::zeros(n_hor * ny, ny);
            for j in 0..n_hor {
                s.view_mut((j * ny, 0), (ny, ny))
                    .copy_from(&DMatrix::identity(ny, ny));
            }
            let fr = -self.q * s.transpose() * &gz;
            f_theta.view_mut((nx, 0), (ny, nz)).copy_from(&fr);
        }
        // Constraints over the whole horizon: [I; -I] Omega z <= W + E theta.
        let m = 2 * n_hor * nu;
        let mut g = DMatrix::zeros(m, nz);
        let mut w = DVector::zeros(m);
        let mut e = DMatrix::zeros(m, p);
        for k in 0..n_hor {
            for i in 0..nu {
                let r = k * nu + i;
                g.row_mut(r).copy_from(&omega.row(r));
                g.row_mut(n_hor * nu + r).copy_from(&(-omega.row(r)));
                w[r] = self.u_hi[i];
                w[n_hor * nu + r] = -self.u_lo[i];
                if has_th && self.throttle_inputs.contains(&i) {
                    e[(r, p - 1)] = -1.0;
                    e[(n_hor * nu + r, p - 1)] = 1.0;
                }
            }
        }
        let mut lb = vec![-self.x_bound; nx];
        let mut ub = vec![self.x_bound; nx];
        if track {
            lb.extend(std::iter::repeat_n(-self.ref_bound, ny));
            ub.extend(std::iter::repeat_n(self.ref_bound, ny));
        }
        if has_th {
            lb.push(self.throttle_range.0);
            ub.push(self.throttle_range.1);
        }
        MpqpProblem {
            h,
            f_theta,
            f: DVector::zeros(nz),
            g,
            w,
            e,
            theta_lb: DVector::from_vec(lb),
            theta_ub: DVector::from_vec(ub),
            theta_poly: None,
        }
    }
}

/// A thesis-sized problem: 5 states, 4 inputs, 3 tracked outputs, a
/// throttle shifting the bounds of inputs 0..3, `N = 2`, `Ns = 1`:
/// 9 parameters, 4 variables (scaled units: inputs in [-1, 1] around the
/// throttle, throttle in [-0.3, 0.3]).
pub fn thesis_sized(seed: u64) -> MpqpProblem {
    let mut s = random_system(5, 4, 3, 0.95, seed);
    s.horizon = 2;
    s.free_moves = 1;
    s.throttle_inputs = vec![0, 1, 2];
    s.throttle_range = (-0.3, 0.3);
    s.x_bound = 1.0;
    s.ref_bound = 1.0;
    s.condense()
}

/// The benchmark problem: 9 parameters (9 states), 8 variables (2 inputs,
/// 4 free moves, horizon 6 with move blocking), about a thousand regions.
pub fn benchmark_9x8() -> MpqpProblem {
    let mut s = random_system(9, 2, 0, 0.98, 7);
    s.horizon = 6;
    s.free_moves = 4;
    s.q = 1.0;
    s.r = 0.05;
    s.x_bound = 20.0;
    s.condense()
}
