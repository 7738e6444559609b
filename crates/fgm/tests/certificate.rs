//! The certificate against clarabel: `J(z after the certified iterations)
//! - J* <= eps` for random theta, cold and warm start, in f64; the f32 and
//! fixed-point solvers within their stated bounds. The full 10^5-theta runs
//! are `cargo run --release -p kestrel-fgm --example certify_report`.
#![allow(clippy::needless_range_loop)] // index loops mirror the textbook formulas

mod common;

use common::{Rng, mpc_problem, random_theta};
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::reference::ReferenceSolver;
use kestrel_fgm::{
    BoxQp, FgmDesign, FgmSettings, Momentum, Preconditioner, Start, WarmStartAssumption,
};
use nalgebra::DVector;

/// Debug-build sample size per problem (the release report uses 10^5).
const SAMPLES: usize = 300;

fn design(seed: u64, nx: usize, nu: usize, nh: usize, pc: Preconditioner) -> FgmDesign {
    let prob = mpc_problem(seed, nx, nu, nh);
    let settings = FgmSettings {
        preconditioner: pc,
        ..FgmSettings::default()
    };
    FgmDesign::new(BoxQp::from_mpqp(&prob).unwrap(), settings).unwrap()
}

fn check_cold(d: &FgmDesign, eps: f64, seed: u64) -> f64 {
    let cert = d.certify(eps).unwrap();
    let data = d.data::<f64>(&cert, None).unwrap();
    let mut reference = ReferenceSolver::new(&d.problem).unwrap();
    let mut rng = Rng::new(seed);
    let mut worst: f64 = f64::NEG_INFINITY;
    for _ in 0..SAMPLES {
        let th = random_theta(&mut rng, &d.problem.theta_lb, &d.problem.theta_ub);
        let best = reference.solve(&th).unwrap();
        assert!(best.polished, "the reference is exact");
        let z = data
            .solve(th.as_slice(), Start::Cold, cert.iterations)
            .unwrap();
        let z = DVector::from_vec(z);
        let b = d.problem.bounds(&th);
        for i in 0..z.len() {
            assert!(
                z[i] >= b.lo[i] - 1e-9 && z[i] <= b.hi[i] + 1e-9,
                "infeasible"
            );
        }
        let gap = d.problem.cost(&z, &th) - best.cost;
        // The polished reference is exact to rounding: no slack.
        assert!(
            gap <= eps,
            "gap {gap} > eps {eps} after {} iterations",
            cert.iterations
        );
        worst = worst.max(gap);
    }
    worst
}

#[test]
fn cold_start_certificate_holds_for_every_preconditioner_and_scheme() {
    for (seed, nx, nu, nh) in [(1, 3, 2, 3), (2, 4, 3, 2)] {
        for pc in [
            Preconditioner::None,
            Preconditioner::Jacobi,
            Preconditioner::OptimalDiagonal,
        ] {
            let d = design(seed, nx, nu, nh, pc);
            let delta = d.delta();
            for rel in [1e-3, 1e-6] {
                let worst = check_cold(&d, rel * delta, seed + 100);
                assert!(worst.is_finite());
            }
        }
    }
    // The table scheme (the mu = 0 path) with its own certificate.
    let mut d = design(3, 3, 2, 3, Preconditioner::OptimalDiagonal);
    d.settings.momentum = Momentum::Table;
    let cert = d.certify(1e-4 * d.delta()).unwrap();
    assert_eq!(cert.scheme, kestrel_fgm::MomentumScheme::Table);
    check_cold(&d, 1e-4 * d.delta(), 7);
}

#[test]
fn warm_start_certificate_holds() {
    let d = design(4, 3, 2, 3, Preconditioner::OptimalDiagonal);
    let eps = 1e-6 * d.delta();
    let cert = d.certify(eps).unwrap();
    let range = &d.problem.theta_ub - &d.problem.theta_lb;
    let assume = WarmStartAssumption {
        prev_eps: eps,
        theta_step: &range * 0.01,
    };
    let warm = d.certify_warm(eps, &assume).unwrap();
    assert!(warm.refined);
    assert!(
        warm.iterations < cert.iterations,
        "{} vs {}",
        warm.iterations,
        cert.iterations
    );
    let data = d.data::<f64>(&cert, Some(warm.iterations)).unwrap();
    let mut reference = ReferenceSolver::new(&d.problem).unwrap();
    let mut rng = Rng::new(11);
    for _ in 0..SAMPLES {
        let th0 = random_theta(&mut rng, &d.problem.theta_lb, &d.problem.theta_ub);
        // Previous solution: certified cold solve at th0 (eps-optimal).
        let prev = data
            .solve(th0.as_slice(), Start::Cold, cert.iterations)
            .unwrap();
        let th = DVector::from_fn(th0.len(), |i, _| {
            (th0[i] + assume.theta_step[i] * rng.uniform(-1.0, 1.0))
                .clamp(d.problem.theta_lb[i], d.problem.theta_ub[i])
        });
        let z = data
            .solve(th.as_slice(), Start::Warm(&prev), warm.iterations)
            .unwrap();
        let gap = d.problem.cost(&DVector::from_vec(z), &th) - reference.solve(&th).unwrap().cost;
        assert!(gap <= eps, "warm gap {gap} > {eps}");
    }
}

fn check_low_precision<S: Scalar>(d: &FgmDesign, eps: f64) -> f64 {
    let cert = d.certify(eps).unwrap();
    let bound = d.rounding_bound::<S>(&cert).expect("constant scheme");
    let lo = d.data::<S>(&cert, None).unwrap();
    let hi = d.data::<f64>(&cert, None).unwrap();
    let mut reference = ReferenceSolver::new(&d.problem).unwrap();
    let mut rng = Rng::new(23);
    let mut worst: f64 = 0.0;
    for _ in 0..SAMPLES {
        let th = random_theta(&mut rng, &d.problem.theta_lb, &d.problem.theta_ub);
        let ths: Vec<S> = th.iter().map(|v| S::from_f64(*v)).collect();
        let zs = lo.solve(&ths, Start::Cold, cert.iterations).unwrap();
        let zs = DVector::from_iterator(zs.len(), zs.iter().map(|v| v.to_f64()));
        let z64 = DVector::from_vec(
            hi.solve(th.as_slice(), Start::Cold, cert.iterations)
                .unwrap(),
        );
        let best = reference.solve(&th).unwrap().cost;
        let gap = d.problem.cost(&zs, &th) - best;
        assert!(
            gap <= bound.cost_bound,
            "{}: gap {gap} > {}",
            bound.scalar,
            bound.cost_bound
        );
        let dist = (&zs - &z64).norm();
        assert!(
            dist <= bound.distance_bound,
            "{}: {dist} > {}",
            bound.scalar,
            bound.distance_bound
        );
        worst = worst.max(dist);
    }
    worst
}

#[test]
fn f32_and_fixed_point_within_their_stated_bounds() {
    let d = design(5, 3, 2, 3, Preconditioner::OptimalDiagonal);
    let eps = 1e-6 * d.delta();
    let w32 = check_low_precision::<f32>(&d, eps);
    let wq = check_low_precision::<Q16>(&d, eps);
    assert!(w32 < wq || wq < 1e-3, "f32 {w32}, Q16 {wq}");
}

#[test]
fn bad_eps_and_assumptions_are_refused() {
    let d = design(6, 2, 2, 2, Preconditioner::Jacobi);
    for eps in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = d.certify(eps).unwrap_err();
        assert!(e.to_string().contains("eps must be a positive"), "{e}");
    }
    let bad = WarmStartAssumption {
        prev_eps: 1.0,
        theta_step: DVector::zeros(1),
    };
    assert!(d.certify_warm(1.0, &bad).is_err());
}

#[test]
fn preconditioning_lowers_the_condition_number_and_iterations() {
    let none = design(8, 4, 3, 3, Preconditioner::None);
    let jac = design(8, 4, 3, 3, Preconditioner::Jacobi);
    let opt = design(8, 4, 3, 3, Preconditioner::OptimalDiagonal);
    let (k0, kj, ko) = (
        none.spectrum.condition(),
        jac.spectrum.condition(),
        opt.spectrum.condition(),
    );
    assert!(ko <= kj * (1.0 + 1e-9) && ko < k0, "{k0} {kj} {ko}");
    let eps = 1e-3;
    assert!(opt.certify(eps).unwrap().iterations <= none.certify(eps).unwrap().iterations);
}

/// The fixed-size kernel (`FgmTables`, `Scalar::tr_mat_vec` on the
/// symmetric `M`) and the run-time-size kernel (`solve_view`, row dots)
/// give bit-identical solutions, in f64, f32 and fixed point, cold and warm.
#[test]
fn fixed_size_kernel_is_bit_identical_to_the_view_kernel() {
    fn check<S: Scalar + core::fmt::Debug>(d: &FgmDesign) {
        let cert = d.certify(1e-6 * d.delta()).unwrap();
        let data = d.data::<S>(&cert, None).unwrap();
        let tables = data.to_tables::<6, 4, 1>().unwrap();
        let mut ws = kestrel_fgm::FgmWorkspace::<S, 6>::new();
        let mut rng = Rng::new(77);
        for _ in 0..50 {
            let th = random_theta(&mut rng, &d.problem.theta_lb, &d.problem.theta_ub);
            let ths: [S; 4] = core::array::from_fn(|i| S::from_f64(th[i]));
            let view = data.solve(&ths, Start::Cold, 7).unwrap();
            let fixed = tables.solve_with(&ths, Start::Cold, 7, &mut ws).unwrap();
            assert_eq!(view.as_slice(), fixed.as_slice());
            let warm_view = data.solve(&ths, Start::Warm(&view), 3).unwrap();
            let warm_fixed = tables
                .solve_with(&ths, Start::Warm(&fixed), 3, &mut ws)
                .unwrap();
            assert_eq!(warm_view.as_slice(), warm_fixed.as_slice());
        }
    }
    let d = design(1, 3, 2, 3, Preconditioner::OptimalDiagonal);
    assert_eq!((d.n(), d.problem.p()), (6, 4));
    check::<f64>(&d);
    check::<f32>(&d);
    check::<Q16>(&d);
}

/// The cold `Delta` is the largest `1/2 e'(L I - H_s) e` over the
/// half-width box, checked against a direct evaluation at every vertex
/// and random interior points, and a quarter of Richter's at most.
#[test]
fn cold_delta_is_the_vertex_maximum_of_the_quadratic_bound() {
    let d = design(2, 4, 3, 2, Preconditioner::Jacobi);
    let n = d.n();
    let l = d.spectrum.l;
    let a = nalgebra::DMatrix::identity(n, n) * l - &d.h_scaled;
    let w = d.problem.max_widths();
    let r = DVector::from_fn(n, |j, _| 0.5 * w[j] / d.d[j]);
    let q = |e: &DVector<f64>| 0.5 * e.dot(&(&a * e));
    let mut brute: f64 = 0.0;
    for mask in 0u32..(1 << n) {
        let e = DVector::from_fn(n, |j, _| if mask >> j & 1 == 1 { r[j] } else { -r[j] });
        brute = brute.max(q(&e));
    }
    assert!(
        (d.delta() - brute).abs() <= 1e-8 * brute,
        "{} vs {brute}",
        d.delta()
    );
    let mut rng = Rng::new(5);
    for _ in 0..1000 {
        let e = DVector::from_fn(n, |j, _| rng.uniform(-r[j], r[j]));
        assert!(q(&e) <= d.delta());
    }
    let cert = d.certify(1e-3).unwrap();
    assert!(cert.delta <= 0.25 * cert.delta_richter * (1.0 + 1e-12));
}

/// The input tolerance: the closed form for a diagonal `H` (`eps = e^2
/// min_j h_jj / 2`), tight (a point with `J - J* = eps` has an input error
/// of exactly `e`), never below the eigenvalue form, and refused for a
/// singular `H` or a bad selection.
#[test]
fn input_tolerance_is_the_closed_form_and_tight() {
    use kestrel_core::formats::MpqpProblem;
    use kestrel_fgm::AppliedInputs;
    let diag = MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1", "H": [[4, 0, 0], [0, 0.5, 0], [0, 0, 2]],
        "F": [[1, 0, 0]], "G": [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
        "W": [100, 100, 100, 100, 100, 100], "E": [[0], [0], [0], [0], [0], [0]],
        "theta_lb": [-1], "theta_ub": [1]}"#,
    )
    .unwrap();
    let d = FgmDesign::new(BoxQp::from_mpqp(&diag).unwrap(), FgmSettings::default()).unwrap();
    let first = d.input_tolerance(2.0, AppliedInputs::FirstMove(1)).unwrap();
    assert!((first.eps - 4.0 * 4.0 / 2.0).abs() < 1e-9, "{}", first.eps);
    let all = d.input_tolerance(2.0, AppliedInputs::All).unwrap();
    assert_eq!(all.worst_variable, 1);
    assert!((all.eps - 4.0 * 0.5 / 2.0).abs() < 1e-9);
    assert!((all.eps_eigenvalue - all.eps).abs() < 1e-9);
    // Tight on a coupled H: z = z* + t H^-1 e_j with J - J* = eps moves z_j by e.
    let prob = mpc_problem(4, 3, 2, 2);
    let d = FgmDesign::new(BoxQp::from_mpqp(&prob).unwrap(), FgmSettings::default()).unwrap();
    let tol = d.input_tolerance(1.0, AppliedInputs::FirstMove(2)).unwrap();
    assert!(tol.eps >= tol.eps_eigenvalue);
    let h = &d.problem.h;
    let hinv = h.clone().try_inverse().unwrap();
    let j = tol.worst_variable;
    let dir = hinv.column(j).into_owned();
    // 1/2 t^2 dir' H dir = eps  (interior optimum: theta with z* = -H^-1 q).
    let t = (2.0 * tol.eps / dir.dot(&(h * &dir))).sqrt();
    assert!(((t * dir[j]).abs() - 1.0).abs() < 1e-9);
    // Any feasible z with J - J* <= eps: random probes never exceed e.
    let th = (&d.problem.theta_lb + &d.problem.theta_ub) * 0.5;
    let best = ReferenceSolver::new(&d.problem)
        .unwrap()
        .solve(&th)
        .unwrap();
    let b = d.problem.bounds(&th);
    let mut rng = Rng::new(9);
    for _ in 0..2000 {
        let z = DVector::from_fn(d.n(), |i, _| {
            (best.z[i] + rng.uniform(-1.5, 1.5)).clamp(b.lo[i], b.hi[i])
        });
        if d.problem.cost(&z, &th) - best.cost <= tol.eps {
            assert!((0..2).all(|i| (z[i] - best.z[i]).abs() <= 1.0 + 1e-6));
        }
    }
    assert!(d.input_tolerance(0.0, AppliedInputs::All).is_err());
    assert!(d.input_tolerance(1.0, AppliedInputs::FirstMove(0)).is_err());
    assert!(
        d.input_tolerance(1.0, AppliedInputs::FirstMove(d.n() + 1))
            .is_err()
    );
    let mut singular = diag.clone();
    singular.h = nalgebra::DMatrix::from_row_slice(3, 3, &[1., 1., 0., 1., 1., 0., 0., 0., 2.]);
    let none = FgmSettings {
        preconditioner: Preconditioner::None,
        ..FgmSettings::default()
    };
    let d = FgmDesign::new(BoxQp::from_mpqp(&singular).unwrap(), none).unwrap();
    assert!(d.input_tolerance(1.0, AppliedInputs::All).is_err());
}
