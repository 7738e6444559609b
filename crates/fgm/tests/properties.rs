//! Laws that hold for every input: the projection, and the monotonicity of
//! the certificate and of the convergence bound.
#![allow(clippy::needless_range_loop)] // index loops mirror the textbook formulas

mod common;

use common::mpc_problem;
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::reference::ReferenceSolver;
use kestrel_fgm::{BoxQp, FgmDesign, FgmSettings, Momentum, Start};
use nalgebra::DVector;
use proptest::prelude::*;

fn design(seed: u64, momentum: Momentum) -> FgmDesign {
    let qp = BoxQp::from_mpqp(&mpc_problem(seed, 3, 2, 2)).unwrap();
    FgmDesign::new(
        qp,
        FgmSettings {
            momentum,
            ..FgmSettings::default()
        },
    )
    .unwrap()
}

fn theta_at(d: &FgmDesign, u: &[f64]) -> DVector<f64> {
    let (lb, ub) = (&d.problem.theta_lb, &d.problem.theta_ub);
    DVector::from_fn(lb.len(), |i, _| lb[i] + (ub[i] - lb[i]) * u[i % u.len()])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// With zero iterations the solver returns the projected gradient step
    /// from the clamped start: the Euclidean projection onto the box, i.e.
    /// inside the box and `(x - P x)'(q - P x) <= 0` for every box point q.
    #[test]
    fn output_is_the_projection(seed in 0u64..6, u in prop::collection::vec(0.0f64..1.0, 4),
                                start in prop::collection::vec(-3000.0f64..3000.0, 4),
                                corner in prop::collection::vec(0.0f64..1.0, 4)) {
        let d = design(seed, Momentum::Auto);
        let cert = d.certify(1.0).unwrap();
        let data = d.data::<f64>(&cert, None).unwrap();
        let th = theta_at(&d, &u);
        let z = DVector::from_vec(data.solve(th.as_slice(), Start::Warm(&start), 0).unwrap());
        let b = d.problem.bounds(&th);
        // Unprojected step in problem units: x = s - D D (H s + q) / L.
        let s = DVector::from_fn(4, |i, _| start[i].clamp(b.lo[i], b.hi[i]));
        let g = &d.problem.h * &s + d.problem.linear_term(&th);
        let x = DVector::from_fn(4, |i, _| s[i] - d.d[i] * d.d[i] * g[i] / d.spectrum.l);
        let q = DVector::from_fn(4, |i, _| b.lo[i] + (b.hi[i] - b.lo[i]) * corner[i]);
        for i in 0..4 {
            prop_assert!(z[i] >= b.lo[i] - 1e-9 && z[i] <= b.hi[i] + 1e-9);
        }
        let scale = 1.0 + x.amax() * q.amax();
        prop_assert!((&x - &z).dot(&(&q - &z)) <= 1e-9 * scale);
    }

    /// Every iterate's cost gap is below the bound lambda_k Delta, for every
    /// k (not only the certified one), for both momentum schemes.
    #[test]
    fn gap_below_the_bound_at_every_iteration(seed in 0u64..6, u in prop::collection::vec(0.0f64..1.0, 4),
                                              table in any::<bool>()) {
        let d = design(seed, if table { Momentum::Table } else { Momentum::Constant });
        let cert = d.certify(1.0).unwrap();
        let data = d.data::<f64>(&cert, Some(40)).unwrap();
        let th = theta_at(&d, &u);
        let best = ReferenceSolver::new(&d.problem).unwrap().solve(&th).unwrap().cost;
        let rate = 1.0 - (d.spectrum.mu / d.spectrum.l).sqrt();
        for k in 0..40usize {
            let z = DVector::from_vec(data.solve(th.as_slice(), Start::Cold, k).unwrap());
            let mut lambda = rate.powi(k as i32);
            if table {
                lambda = lambda.min(4.0 / ((k + 2) as f64).powi(2));
            }
            let gap = d.problem.cost(&z, &th) - best;
            prop_assert!(gap <= lambda * d.delta() + 1e-7 * (1.0 + best.abs()), "k {k}: {gap} > {}", lambda * d.delta());
        }
    }

    /// Certified iterations never increase with eps; the recommended start
    /// never needs more than the cold one, and it is the warm start exactly
    /// when the warm certificate is shorter. (The warm certificate itself may
    /// exceed the cold one: its fallback covers a start anywhere in the box,
    /// four times the centre's Delta.)
    #[test]
    fn certificate_is_monotone(seed in 0u64..6, a in -8.0f64..6.0, b in -8.0f64..6.0) {
        let d = design(seed, Momentum::Auto);
        let (lo, hi) = (10f64.powf(a.min(b)), 10f64.powf(a.max(b)));
        let (cl, ch) = (d.certify(lo).unwrap(), d.certify(hi).unwrap());
        prop_assert!(ch.iterations <= cl.iterations);
        prop_assert!(ch.sublinear_bound.unwrap() <= cl.sublinear_bound.unwrap());
        let step = (&d.problem.theta_ub - &d.problem.theta_lb) * 0.02;
        let w = d.certify_warm(lo, &kestrel_fgm::WarmStartAssumption { prev_eps: lo, theta_step: step }).unwrap();
        prop_assert_eq!(&w.cold, &cl);
        prop_assert!(w.recommended_iterations() <= cl.iterations);
        prop_assert_eq!(w.recommended() == kestrel_fgm::RecommendedStart::Warm, w.iterations < cl.iterations);
        if !w.refined {
            // The fallback is the anywhere-start bound: never shorter than cold.
            prop_assert!(w.iterations >= cl.iterations);
        }
    }

    /// The fixed-point solver's output stays inside the true box (the box
    /// tables are shrunk by their rounding bound).
    #[test]
    fn fixed_point_output_is_feasible(seed in 0u64..6, u in prop::collection::vec(0.0f64..1.0, 4)) {
        let d = design(seed, Momentum::Constant);
        let cert = d.certify(1e-3).unwrap();
        let data = d.data::<Q16>(&cert, None).unwrap();
        let th = theta_at(&d, &u);
        let tq: Vec<Q16> = th.iter().map(|v| Q16::from_f64(*v)).collect();
        let z = data.solve(&tq, Start::Cold, cert.iterations).unwrap();
        let thq = DVector::from_iterator(th.len(), tq.iter().map(|v| v.to_f64()));
        let b = d.problem.bounds(&thq);
        for i in 0..4 {
            // Only the output scaling z = D v rounds after the clamp.
            let slack = 2.0 * Q16::RESOLUTION * (1.0 + z[i].to_f64().abs());
            prop_assert!(z[i].to_f64() >= b.lo[i] - slack && z[i].to_f64() <= b.hi[i] + slack);
        }
    }
}

#[test]
fn beta_table_follows_the_errata_and_converges() {
    let d = design(1, Momentum::Table);
    let betas = d.beta_table(400);
    assert!(betas.iter().all(|b| (0.0..1.0).contains(b)));
    // alpha_i -> sqrt(mu/L), so beta_i -> the constant momentum.
    assert!(
        (betas[399] - d.constant_beta()).abs() < 1e-6,
        "{} vs {}",
        betas[399],
        d.constant_beta()
    );
    // Direct recomputation of the errata formula for the first entries.
    let q = d.spectrum.mu / d.spectrum.l;
    let mut a: f64 = (-(1.0 - q) + ((1.0 - q) * (1.0 - q) + 4.0).sqrt()) / 2.0;
    // gamma_0 = a (a L - mu) / (1 - a) = L.
    assert!((a * (a - q) / (1.0 - a) - 1.0).abs() < 1e-12);
    for b in betas.iter().take(5) {
        let next = {
            // alpha_{i+1}^2 = (1 - alpha_{i+1}) alpha_i^2 + q alpha_{i+1}
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..200 {
                let m: f64 = 0.5 * (lo + hi);
                if m * m - ((1.0 - m) * a * a + q * m) < 0.0 {
                    lo = m
                } else {
                    hi = m
                }
            }
            0.5 * (lo + hi)
        };
        assert!((b - a * (1.0 - a) / (a * a + next)).abs() < 1e-12);
        a = next;
    }
}
