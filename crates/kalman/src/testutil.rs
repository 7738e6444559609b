//! Test helpers: random problems and an independent Riccati solver.
//!
//! The reference solver shares no code with [`crate::dare`]: value
//! iteration of the Riccati difference equation from `X = 0` until the
//! gain is stabilising, then Newton–Kleinman (Hewer) iterations whose Stein
//! equations are solved by Kronecker vectorisation (n <= 12) or by
//! summing the squared series.

use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::SplitMix64;

/// Random test data from the workspace's seeded generator
/// (`rand_xoshiro::SplitMix64`) with normal deviates (`rand_distr`).
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::seed_from_u64(seed))
    }
    pub fn normal(&mut self) -> f64 {
        self.0.sample(StandardNormal)
    }
    pub fn matrix(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.normal())
    }
    /// A random orthogonal matrix (Q factor of a Gaussian matrix).
    pub fn orthogonal(&mut self, n: usize) -> DMatrix<f64> {
        self.matrix(n, n).qr().q()
    }
    /// A symmetric positive definite matrix with the given condition number.
    pub fn spd(&mut self, n: usize, cond: f64) -> DMatrix<f64> {
        let u = self.orthogonal(n);
        let d = DVector::from_fn(n, |i, _| {
            if n == 1 {
                1.0
            } else {
                cond.powf(-(i as f64) / (n - 1) as f64)
            }
        });
        let mut r = &u * DMatrix::from_diagonal(&d) * u.transpose();
        crate::dare::symmetrize(&mut r);
        r
    }
}

/// A random stabilisable and detectable DARE problem.
pub struct Problem {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub q: DMatrix<f64>,
    pub r: DMatrix<f64>,
    pub s: Option<DMatrix<f64>>,
}

/// Options for [`random_problem`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Kind {
    /// Zero about a third of the columns of A (rank-deficient A).
    pub singular_a: bool,
    /// Condition number of R (1 when zero).
    pub r_cond: f64,
    /// Add a cross weight S.
    pub cross: bool,
}

pub fn random_problem(n: usize, seed: u64, kind: Kind) -> Problem {
    let mut rng = Rng::new(seed);
    let m = 1 + n / 4;
    let p = 1 + n / 3;
    // Spectral radius near 1.1: a few unstable modes.
    let mut a = rng.matrix(n, n) * (1.1 / (n as f64).sqrt());
    if kind.singular_a {
        for j in (0..n).step_by(3) {
            a.column_mut(j).fill(0.0);
        }
    }
    let b = rng.matrix(n, m);
    let c = rng.matrix(p, n);
    let cond = if kind.r_cond > 0.0 { kind.r_cond } else { 1.0 };
    let r0 = rng.spd(m, cond);
    let (q, r, s) = if kind.cross {
        // [Q S; S' R] = [C E]'[C E] + diag(0, R0) is PSD.
        let e = rng.matrix(p, m) * 0.3;
        (
            c.transpose() * &c,
            e.transpose() * &e + &r0,
            Some(c.transpose() * &e),
        )
    } else {
        (c.transpose() * &c, r0, None)
    };
    let mut q = q;
    let mut r = r;
    crate::dare::symmetrize(&mut q);
    crate::dare::symmetrize(&mut r);
    Problem { a, b, q, r, s }
}

/// Spectral radius (through the iteration-limited eigenvalue routine:
/// nalgebra's own `complex_eigenvalues` can cycle for ever).
fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    crate::dare::eigenvalues(m)
        .expect("eigenvalues converge")
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// The optimal gain for a given X (solving with a full LU, not Cholesky).
fn gain_for(p: &Problem, x: &DMatrix<f64>) -> DMatrix<f64> {
    let bt = p.b.transpose();
    let lhs = &p.r + &bt * x * &p.b;
    let mut rhs = &bt * x * &p.a;
    if let Some(s) = &p.s {
        rhs += s.transpose();
    }
    lhs.lu().solve(&rhs).expect("R + B'XB invertible")
}

/// Solves `X = F' X F + W` for stable `F`.
fn stein(f: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
    let n = f.nrows();
    if n <= 12 {
        // vec(F'XF) = (F' kron F') vec(X) for column-major vec.
        let ft = f.transpose();
        let kron = ft.kronecker(&ft);
        let lhs = DMatrix::identity(n * n, n * n) - kron;
        let rhs = DVector::from_column_slice(w.as_slice());
        let v = lhs.lu().solve(&rhs).expect("stable F");
        DMatrix::from_column_slice(n, n, v.as_slice())
    } else {
        // Squared series: X_{j+1} = X_j + F_j' X_j F_j, F_{j+1} = F_j^2.
        let mut x = w.clone();
        let mut fj = f.clone();
        for _ in 0..64 {
            let inc = fj.transpose() * &x * &fj;
            x += &inc;
            if inc.norm() <= 1e-18 * x.norm() {
                break;
            }
            fj = &fj * &fj;
        }
        x
    }
}

/// Independent reference: value iteration to a stabilising gain, then Newton–Kleinman.
pub fn reference_dare(p: &Problem) -> DMatrix<f64> {
    let n = p.a.nrows();
    let mut x = DMatrix::<f64>::zeros(n, n);
    let mut k = gain_for(p, &x);
    let mut it = 0;
    while spectral_radius(&(&p.a - &p.b * &k)) >= 0.999 {
        for _ in 0..5 {
            let g = gain_for(p, &x);
            let mut cross = p.a.transpose() * &x * &p.b;
            if let Some(s) = &p.s {
                cross += s;
            }
            x = p.a.transpose() * &x * &p.a - cross * &g + &p.q;
            x = (&x + x.transpose()) * 0.5;
        }
        k = gain_for(p, &x);
        it += 1;
        assert!(it < 20_000, "value iteration did not stabilise");
    }
    for _ in 0..100 {
        let f = &p.a - &p.b * &k;
        let mut w = &p.q + k.transpose() * &p.r * &k;
        if let Some(s) = &p.s {
            w -= s * &k + k.transpose() * s.transpose();
        }
        let xn = stein(&f, &w);
        let xn = (&xn + xn.transpose()) * 0.5;
        let change = (&xn - &x).norm();
        x = xn;
        k = gain_for(p, &x);
        if change <= 1e-14 * x.norm() {
            break;
        }
    }
    x
}
