//! Random strictly convex QPs checked against their KKT conditions,
//! computed here from the original `H, q, G` (not the solver's factors).
// Reference computations index dense matrices the textbook way.
#![allow(clippy::needless_range_loop)]

use crate::{QpData, QpSettings, QpSolver, Start, index_len, scalar_len};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// A random QP with a feasible point (bounds around a random `z0`), some
/// bounds infinite, `H = A A' + 0.5 I`.
pub(crate) struct RandomQp {
    pub n: usize,
    pub m: usize,
    pub h: Vec<f64>,
    pub q: Vec<f64>,
    pub g: Vec<f64>,
    pub l: Vec<f64>,
    pub u: Vec<f64>,
    pub lb: Vec<f64>,
    pub ub: Vec<f64>,
}

impl RandomQp {
    pub fn new(seed: u64, n: usize, m: usize) -> Self {
        let mut rng = SplitMix64::seed_from_u64(seed);
        let mut r = move || 2.0 * rng.random::<f64>() - 1.0;
        let a: Vec<f64> = (0..n * n).map(|_| r()).collect();
        let mut h = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                h[i * n + j] = (0..n).map(|k| a[i * n + k] * a[j * n + k]).sum::<f64>()
                    + if i == j { 0.5 } else { 0.0 };
            }
        }
        let q: Vec<f64> = (0..n).map(|_| 5.0 * r()).collect();
        let g: Vec<f64> = (0..m * n).map(|_| r()).collect();
        let z0: Vec<f64> = (0..n).map(|_| 0.5 * r()).collect();
        let mut l = Vec::new();
        let mut u = Vec::new();
        for row in g.chunks(n) {
            let v: f64 = row.iter().zip(&z0).map(|(a, b)| a * b).sum();
            let lo = v - 0.5 * (r() + 1.0);
            let hi = v + 0.5 * (r() + 1.0);
            l.push(if r() > 0.5 { f64::NEG_INFINITY } else { lo });
            u.push(if r() > 0.7 { f64::INFINITY } else { hi });
        }
        let mut lb = Vec::new();
        let mut ub = Vec::new();
        for &z in &z0 {
            let lo = z - (r() + 1.0);
            let hi = z + (r() + 1.0);
            lb.push(if r() > 0.6 { f64::NEG_INFINITY } else { lo });
            ub.push(if r() > 0.6 { f64::INFINITY } else { hi });
        }
        RandomQp {
            n,
            m,
            h,
            q,
            g,
            l,
            u,
            lb,
            ub,
        }
    }

    pub fn data(&self) -> QpData<'_, f64> {
        QpData {
            q: &self.q,
            l: &self.l,
            u: &self.u,
            lb: &self.lb,
            ub: &self.ub,
        }
    }

    /// The largest KKT residual of `(z, mu)`, relative to the data's
    /// scale: stationarity, primal feasibility, dual sign and
    /// complementarity.
    pub fn kkt_residual(&self, z: &[f64], mu: &[f64]) -> f64 {
        let (n, m) = (self.n, self.m);
        let scale = 1.0 + self.q.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        let mut worst = 0.0_f64;
        for i in 0..n {
            let mut r = self.q[i] + mu[m + i];
            for j in 0..n {
                r += self.h[i * n + j] * z[j];
            }
            for k in 0..m {
                r += self.g[k * n + i] * mu[k];
            }
            worst = worst.max(r.abs() / scale);
        }
        let rows = (0..m).map(|k| {
            let v: f64 = (0..n).map(|j| self.g[k * n + j] * z[j]).sum();
            (v, self.l[k], self.u[k], mu[k])
        });
        let bounds = (0..n).map(|i| (z[i], self.lb[i], self.ub[i], mu[m + i]));
        for (v, lo, hi, mu) in rows.chain(bounds) {
            worst = worst.max(v - hi).max(lo - v);
            if mu > 0.0 {
                worst = worst.max((v - hi).abs() * mu.abs().min(1.0));
                worst = worst.max(if hi.is_finite() { 0.0 } else { mu });
            } else if mu < 0.0 {
                worst = worst.max((v - lo).abs() * mu.abs().min(1.0));
                worst = worst.max(if lo.is_finite() { 0.0 } else { -mu });
            }
        }
        worst
    }
}

/// Solves `qp` in f64 from `start` (after a cold solve when warm):
/// `(z, mu, iterations)`.
pub(crate) fn solve(
    qp: &RandomQp,
    settings: QpSettings,
) -> Result<(Vec<f64>, Vec<f64>, usize), crate::QpError> {
    let mut s = vec![0.0; scalar_len(qp.n, qp.m)];
    let mut ix = vec![0; index_len(qp.n, qp.m)];
    let mut solver = QpSolver::new(qp.n, qp.m, &qp.h, &qp.g, settings, &mut s, &mut ix)?;
    let info = solver.solve(&qp.data(), Start::Cold)?;
    // The factor, updated through every add and remove, equals M.
    assert!(
        solver.factor_residual() < 1e-10,
        "{:e}",
        solver.factor_residual()
    );
    let mut z = vec![0.0; qp.n];
    let mut mu = vec![0.0; qp.n + qp.m];
    solver.solution(&mut z)?;
    solver.multipliers(&mut mu)?;
    Ok((z, mu, info.iterations))
}

#[test]
fn random_qps_satisfy_kkt_to_1e9() {
    let mut worst = 0.0_f64;
    let mut max_iter = 0;
    for seed in 0..2000 {
        let n = 1 + (seed as usize % 10);
        let m = (seed as usize * 7) % 16;
        let qp = RandomQp::new(seed, n, m);
        let (z, mu, it) = solve(&qp, QpSettings::default()).unwrap();
        let r = qp.kkt_residual(&z, &mu);
        assert!(r < 1e-9, "seed {seed}: KKT residual {r:e}");
        worst = worst.max(r);
        max_iter = max_iter.max(it);
    }
    assert!(max_iter > 3, "the problems must exercise the active set");
    eprintln!("worst KKT residual {worst:e}, most iterations {max_iter}");
}

#[test]
fn warm_start_from_the_optimal_set_takes_no_iteration() {
    for seed in 0..300 {
        let qp = RandomQp::new(seed + 10_000, 6, 10);
        let mut s = vec![0.0; scalar_len(qp.n, qp.m)];
        let mut ix = vec![0; index_len(qp.n, qp.m)];
        let mut solver = QpSolver::new(
            qp.n,
            qp.m,
            &qp.h,
            &qp.g,
            QpSettings::default(),
            &mut s,
            &mut ix,
        )
        .unwrap();
        solver.solve(&qp.data(), Start::Cold).unwrap();
        let set: Vec<_> = solver.active_set().collect();
        let mut z = vec![0.0; qp.n];
        solver.solution(&mut z).unwrap();
        // Through an explicit set (the firmware's stored set) as well.
        solver.set_active_set(&set).unwrap();
        let warm = solver.solve(&qp.data(), Start::Warm).unwrap();
        assert!(
            warm.iterations <= 1,
            "seed {seed}: {} iterations",
            warm.iterations
        );
        let mut zw = vec![0.0; qp.n];
        solver.solution(&mut zw).unwrap();
        for (a, b) in z.iter().zip(&zw) {
            assert!((a - b).abs() < 1e-10);
        }
    }
}

#[test]
fn f32_solution_within_stated_bound_of_f64() {
    // Bound stated in docs/qp.md: |z_f32 - z_f64|_inf <= 1e-4 (1 + |z|_inf)
    // on these problems (cond(H) up to ~1e3).
    let mut worst = 0.0_f64;
    for seed in 0..500 {
        let qp = RandomQp::new(seed + 20_000, 5, 8);
        let (z, _, _) = solve(&qp, QpSettings::default()).unwrap();
        let c = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let (h, g, q, l, u, lb, ub) = (
            c(&qp.h),
            c(&qp.g),
            c(&qp.q),
            c(&qp.l),
            c(&qp.u),
            c(&qp.lb),
            c(&qp.ub),
        );
        let mut s = vec![0.0_f32; scalar_len(qp.n, qp.m)];
        let mut ix = vec![0; index_len(qp.n, qp.m)];
        let mut solver =
            QpSolver::new(qp.n, qp.m, &h, &g, QpSettings::for_f32(), &mut s, &mut ix).unwrap();
        let data = QpData {
            q: &q,
            l: &l,
            u: &u,
            lb: &lb,
            ub: &ub,
        };
        solver.solve(&data, Start::Cold).unwrap();
        let mut z32 = vec![0.0_f32; qp.n];
        solver.solution(&mut z32).unwrap();
        let norm = z.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        let err = z
            .iter()
            .zip(&z32)
            .fold(0.0_f64, |a, (x, y)| a.max((x - *y as f64).abs()));
        worst = worst.max(err / (1.0 + norm));
    }
    eprintln!("f32: worst |z32 - z64| / (1 + |z|) = {worst:e}");
    assert!(worst < 1e-4, "{worst:e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    /// For every seed and size the solver returns a KKT point (the random
    /// problems are feasible by construction).
    #[test]
    fn kkt_holds_for_all_random_problems(seed in any::<u64>(), n in 1usize..9, m in 0usize..14) {
        let qp = RandomQp::new(seed, n, m);
        let (z, mu, _) = solve(&qp, QpSettings::default()).unwrap();
        prop_assert!(qp.kkt_residual(&z, &mu) < 1e-9);
    }
}

/// Any value, including NaN, infinities and huge magnitudes.
fn wild() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -10.0..10.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(1e300),
        1 => Just(0.0),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    /// Warm start from the optimal active set: no more than one change,
    /// the same solution.
    #[test]
    fn warm_start_from_optimum_is_immediate(seed in any::<u64>(), n in 1usize..9, m in 0usize..14) {
        let qp = RandomQp::new(seed, n, m);
        let mut s = vec![0.0; scalar_len(n, m)];
        let mut ix = vec![0; index_len(n, m)];
        let mut solver = QpSolver::new(n, m, &qp.h, &qp.g, QpSettings::default(), &mut s, &mut ix).unwrap();
        solver.solve(&qp.data(), Start::Cold).unwrap();
        let mut z = vec![0.0; n];
        solver.solution(&mut z).unwrap();
        let warm = solver.solve(&qp.data(), Start::Warm).unwrap();
        prop_assert!(warm.iterations <= 1);
        let mut zw = vec![0.0; n];
        solver.solution(&mut zw).unwrap();
        for (a, b) in z.iter().zip(&zw) {
            prop_assert!((a - b).abs() <= 1e-10 * (1.0 + a.abs()));
        }
    }

    /// No input makes the solver panic: arbitrary (non-finite, indefinite,
    /// inconsistent) data and warm-start sets give a result or an error.
    #[test]
    fn never_panics(
        n in 1usize..5,
        m in 0usize..5,
        vals in proptest::collection::vec(wild(), 80),
        set in proptest::collection::vec((0usize..12, any::<bool>()), 0..6),
        cap in 1usize..20,
    ) {
        let v = |k: usize| vals[k % vals.len()];
        let h: Vec<f64> = (0..n * n).map(|k| v(k) + if k % (n + 1) == 0 { 20.0 } else { 0.0 }).collect();
        let g: Vec<f64> = (0..m * n).map(|k| v(k + 17)).collect();
        let q: Vec<f64> = (0..n).map(|k| v(k + 31)).collect();
        let l: Vec<f64> = (0..m).map(|k| v(k + 41)).collect();
        let u: Vec<f64> = (0..m).map(|k| v(k + 47)).collect();
        let lb: Vec<f64> = (0..n).map(|k| v(k + 53)).collect();
        let ub: Vec<f64> = (0..n).map(|k| v(k + 61)).collect();
        let mut s = vec![0.0; scalar_len(n, m)];
        let mut ix = vec![0; index_len(n, m)];
        let settings = QpSettings { max_iterations: cap, ..QpSettings::default() };
        if let Ok(mut solver) = QpSolver::new(n, m, &h, &g, settings, &mut s, &mut ix) {
            let data = QpData { q: &q, l: &l, u: &u, lb: &lb, ub: &ub };
            let warm: Vec<_> = set
                .iter()
                .map(|&(index, up)| crate::ActiveConstraint {
                    index,
                    side: if up { crate::Side::Upper } else { crate::Side::Lower },
                })
                .collect();
            let _ = solver.solve(&data, Start::Cold);
            let _ = solver.solve(&data, Start::Warm);
            if solver.set_active_set(&warm).is_ok() {
                let _ = solver.solve(&data, Start::Warm);
            }
            let mut z = vec![0.0; n];
            prop_assert!(solver.solution(&mut z).is_ok());
        }
    }
}
