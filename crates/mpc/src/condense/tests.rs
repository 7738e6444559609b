use super::*;
use crate::constraints::{Bounds, Parameter};
use crate::design::{Blocking, Weight};
use crate::qp::{QpSettings, ReferenceSolver, kkt_residuals, solve_dense};
use kestrel_core::formats::SsModel;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// Reproducible random data from the workspace's seeded generator,
/// `rand_xoshiro::SplitMix64`.
pub(crate) struct Rng(SplitMix64);
impl Rng {
    pub(crate) fn new(seed: u64) -> Self {
        Rng(SplitMix64::seed_from_u64(seed))
    }
    /// Uniform in [-1, 1).
    pub(crate) fn next(&mut self) -> f64 {
        self.0.random::<f64>() * 2.0 - 1.0
    }
    pub(crate) fn mat(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.next())
    }
    pub(crate) fn psd(&mut self, n: usize, floor: f64) -> DMatrix<f64> {
        let l = self.mat(n, n);
        &l * l.transpose() + DMatrix::identity(n, n) * floor
    }
}

/// A random discrete model with spectral radius about 0.95.
pub(crate) fn random_model(rng: &mut Rng, nx: usize, nu: usize, ny: usize) -> SsModel {
    let a0 = rng.mat(nx, nx);
    let rho = kestrel_core::eig::spectral_radius(&a0).unwrap();
    let a = a0 * (0.95 / rho.max(1e-3));
    SsModel::new(
        0.02,
        a,
        rng.mat(nx, nu),
        rng.mat(ny, nx),
        DMatrix::zeros(ny, nu),
    )
    .unwrap()
}

/// The direct (uncondensed) problem in the variables
/// `v = [x_0, ..., x_N, u_0, ..., u_{N-1}]`, built from the model and
/// weights only, and solved with clarabel. Returns the inputs of each
/// block and the optimal cost (constant included).
#[allow(clippy::too_many_arguments)]
fn solve_uncondensed(
    m: &SsModel,
    q1: &DMatrix<f64>,
    q2: &DMatrix<f64>,
    term_state: &DMatrix<f64>,
    term_lin: &DVector<f64>,
    term_const: f64,
    blocks: &[usize],
    bounds: &Bounds,
    x0: &DVector<f64>,
    r: &DVector<f64>,
    throttle: f64,
) -> (DVector<f64>, f64) {
    let (nx, nu) = (m.nx(), m.nu());
    let n_h: usize = blocks.iter().sum();
    let nv = (n_h + 1) * nx + n_h * nu;
    let xi = |j: usize| j * nx;
    let ui = |j: usize| (n_h + 1) * nx + j * nu;
    let mut p = DMatrix::zeros(nv, nv);
    let mut q = DVector::zeros(nv);
    let mut cst = term_const;
    let cqc = m.c.transpose() * q1 * &m.c;
    let cqr = m.c.transpose() * q1 * r;
    for j in 0..n_h {
        p.view_mut((xi(j), xi(j)), (nx, nx)).copy_from(&cqc);
        q.rows_mut(xi(j), nx).copy_from(&(-&cqr));
        cst += 0.5 * r.dot(&(q1 * r));
        p.view_mut((ui(j), ui(j)), (nu, nu)).copy_from(q2);
    }
    p.view_mut((xi(n_h), xi(n_h)), (nx, nx))
        .copy_from(term_state);
    q.rows_mut(xi(n_h), nx).copy_from(term_lin);
    let block_of = Blocking::new(blocks.to_vec()).unwrap().block_of_step();
    let n_eq = nx + n_h * nx + (1..n_h).filter(|&j| block_of[j] == block_of[j - 1]).count() * nu;
    let mut a_eq = DMatrix::zeros(n_eq, nv);
    let mut b_eq = DVector::zeros(n_eq);
    a_eq.view_mut((0, 0), (nx, nx))
        .copy_from(&DMatrix::identity(nx, nx));
    b_eq.rows_mut(0, nx).copy_from(x0);
    let mut row = nx;
    for j in 0..n_h {
        a_eq.view_mut((row, xi(j + 1)), (nx, nx))
            .copy_from(&DMatrix::identity(nx, nx));
        a_eq.view_mut((row, xi(j)), (nx, nx)).copy_from(&(-&m.a));
        a_eq.view_mut((row, ui(j)), (nx, nu)).copy_from(&(-&m.b));
        row += nx;
    }
    for j in 1..n_h {
        if block_of[j] == block_of[j - 1] {
            a_eq.view_mut((row, ui(j)), (nu, nu))
                .copy_from(&DMatrix::identity(nu, nu));
            a_eq.view_mut((row, ui(j - 1)), (nu, nu))
                .copy_from(&(-DMatrix::identity(nu, nu)));
            row += nu;
        }
    }
    let at = bounds.at(&[throttle]);
    let mut a_in = DMatrix::zeros(2 * n_h * nu, nv);
    let mut b_in = DVector::zeros(2 * n_h * nu);
    for j in 0..n_h {
        for i in 0..nu {
            a_in[(j * nu + i, ui(j) + i)] = 1.0;
            b_in[j * nu + i] = at.upper[i];
            a_in[(n_h * nu + j * nu + i, ui(j) + i)] = -1.0;
            b_in[n_h * nu + j * nu + i] = -at.lower[i];
        }
    }
    let v = solve_dense(&p, &q, &a_eq, &b_eq, &a_in, &b_in).unwrap();
    let obj = 0.5 * v.dot(&(&p * &v)) + q.dot(&v) + cst;
    let mut starts = Vec::new();
    let mut s = 0;
    for &l in blocks {
        starts.push(s);
        s += l;
    }
    let z = DVector::from_iterator(
        starts.len() * nu,
        starts
            .iter()
            .flat_map(|&j| v.rows(ui(j), nu).iter().copied().collect::<Vec<_>>()),
    );
    (z, obj)
}

#[test]
fn condensed_matches_uncondensed_clarabel() {
    let mut rng = Rng::new(7);
    let cases: &[(usize, &[usize])] = &[
        (1, &[1]),
        (2, &[2]),
        (2, &[1, 1]),
        (4, &[1, 3]),
        (5, &[1, 1, 1, 1, 1]),
        (10, &[1, 1, 2, 6]),
    ];
    let (mut checked, mut active) = (0, 0);
    for (case, &(n_h, blocks)) in cases.iter().enumerate() {
        for terminal_kind in 0..3 {
            let (nx, nu, ny) = (3 + case % 2, 2, 2);
            let m = random_model(&mut rng, nx, nu, ny);
            let q1 = rng.psd(ny, 0.5) * 10.0;
            let q2 = rng.psd(nu, 0.1) * 0.1;
            let pinv = m.c.clone().pseudo_inverse(1e-12).unwrap();
            let (terminal, pt) = match terminal_kind {
                0 => (Terminal::StageWeight, None),
                1 => {
                    let q1n = rng.psd(ny, 0.2);
                    (Terminal::Output(Weight::Matrix(q1n.clone())), Some(q1n))
                }
                _ => {
                    let pm = rng.psd(nx, 0.1);
                    (Terminal::State(pm.clone()), None)
                }
            };
            // Tight, loose and medium bounds, so both regimes occur.
            let wide = [1.0, 30.0, 4.0][terminal_kind];
            let mut bounds = Bounds::new(
                DVector::from_fn(nu, |_, _| wide * (-0.5 - 0.3 * rng.next().abs())),
                DVector::from_fn(nu, |_, _| wide * (0.4 + 0.3 * rng.next().abs())),
            );
            let mut parameters = Vec::new();
            if case % 2 == 0 {
                bounds = bounds.shifted(DMatrix::from_fn(nu, 1, |i, _| -0.2 * i as f64));
                parameters.push(Parameter::new("throttle", -1.0, 1.0));
            }
            let settings = MpcSettings {
                horizon: n_h,
                blocking: Some(Blocking::new(blocks.to_vec()).unwrap()),
                q1: Weight::Matrix(q1.clone()),
                q2: Weight::Matrix(q2.clone()),
                terminal: terminal.clone(),
                state_bound: 3.0,
                reference_bound: 2.0,
                input_bounds: Some(bounds.clone()),
                parameters,
                ..MpcSettings::default()
            };
            let prob = MpcProblem::build(&m, &settings).unwrap();
            let mpqp = prob.to_mpqp();
            let mut solver = ReferenceSolver::new(&mpqp, QpSettings::default()).unwrap();
            for _ in 0..4 {
                let x0 = DVector::from_fn(nx, |_, _| 3.0 * rng.next());
                let r = DVector::from_fn(ny, |_, _| 2.0 * rng.next());
                let th = rng.next();
                let mut rr: Vec<f64> = r.iter().copied().collect();
                if !settings.parameters.is_empty() {
                    rr.push(th);
                }
                let theta = prob.theta(x0.as_slice(), &rr).unwrap();
                let sol = solver.solve(&theta).unwrap();
                let kkt = kkt_residuals(&mpqp, &theta, &sol.z, &sol.lambda);
                assert!(kkt.max() < 1e-6, "KKT residuals {kkt:?}");
                active += usize::from(sol.lambda.amax() > 1e-6);
                let (pterm, lin, cst) = match (&terminal, &pt) {
                    (Terminal::StageWeight, _) => (
                        m.c.transpose() * &q1 * &m.c,
                        -(m.c.transpose() * &q1 * &r),
                        0.5 * r.dot(&(&q1 * &r)),
                    ),
                    (Terminal::Output(_), Some(q1n)) => (
                        m.c.transpose() * q1n * &m.c,
                        -(m.c.transpose() * q1n * &r),
                        0.5 * r.dot(&(q1n * &r)),
                    ),
                    (Terminal::State(pm), _) => {
                        let xr = &pinv * &r;
                        (pm.clone(), -(pm * &xr), 0.5 * xr.dot(&(pm * &xr)))
                    }
                    _ => unreachable!(),
                };
                let (z_ref, j_ref) = solve_uncondensed(
                    &m, &q1, &q2, &pterm, &lin, cst, blocks, &bounds, &x0, &r, th,
                );
                let scale = z_ref.amax().max(1.0);
                assert!(
                    (&sol.z - &z_ref).amax() < 1e-5 * scale,
                    "N = {n_h}, blocks {blocks:?}, terminal {terminal_kind}: condensed {} vs direct {}",
                    sol.z,
                    z_ref
                );
                let j = prob.cost(&sol.z, &theta);
                assert!(
                    (j - j_ref).abs() < 1e-6 * j_ref.abs().max(1.0),
                    "cost {j} vs direct {j_ref}"
                );
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 6 * 3 * 4);
    // Both regimes are exercised: some solutions with active bounds, some without.
    assert!(
        active > 10 && active < checked - 10,
        "{active} of {checked} active"
    );
}

#[test]
fn lq_terminal_weight_solves_riccati_and_gives_lqr_law() {
    let mut rng = Rng::new(21);
    for n_h in [1, 2, 5] {
        let m = random_model(&mut rng, 4, 2, 2);
        let q1 = rng.psd(2, 0.5);
        let q2 = rng.psd(2, 0.2);
        let settings = MpcSettings {
            horizon: n_h,
            q1: Weight::Matrix(q1.clone()),
            q2: Weight::Matrix(q2.clone()),
            terminal: Terminal::Lq,
            ..MpcSettings::default()
        };
        let wide = Bounds::new(
            DVector::from_element(2, -1e3),
            DVector::from_element(2, 1e3),
        );
        let p = MpcProblem::build(
            &m,
            &MpcSettings {
                input_bounds: Some(wide),
                ..settings
            },
        )
        .unwrap();
        // (7.18) corrected: A'SA - S - A'SB (Q2 + B'SB)^-1 B'SA + C'Q1C = 0.
        let (a, b, s) = (&m.a, &m.b, &p.terminal_weight);
        let bsb = q2 + b.transpose() * s * b;
        let k = bsb
            .clone()
            .cholesky()
            .unwrap()
            .solve(&(b.transpose() * s * a));
        let res =
            a.transpose() * s * a - s - a.transpose() * s * b * &k + m.c.transpose() * &q1 * &m.c;
        assert!(
            res.amax() < 1e-9 * s.amax().max(1.0),
            "Riccati residual {}",
            res.amax()
        );
        // With the cost-to-go as terminal weight and no active bound, the
        // MPC's first move is the LQ law u = -K x (principle of optimality).
        let mut solver = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
        for _ in 0..3 {
            let x = DVector::from_fn(4, |_, _| rng.next());
            let sol = solver
                .solve(&p.theta(x.as_slice(), &[0.0, 0.0]).unwrap())
                .unwrap();
            let u_lq = -(&k * &x);
            assert!((sol.z.rows(0, 2) - &u_lq).amax() < 1e-6, "N = {n_h}");
        }
    }
}

/// Direct rollout of the cost (6.3a) for the output terminal weight.
fn rollout_cost(
    m: &SsModel,
    q1: &DMatrix<f64>,
    q2: &DMatrix<f64>,
    blocks: &[usize],
    x0: &DVector<f64>,
    r: &DVector<f64>,
    z: &DVector<f64>,
) -> f64 {
    let nu = m.nu();
    let mut x = x0.clone();
    let mut j = 0.0;
    for (b, &l) in blocks.iter().enumerate() {
        let u = z.rows(b * nu, nu).into_owned();
        for _ in 0..l {
            let e = &m.c * &x - r;
            j += 0.5 * e.dot(&(q1 * &e)) + 0.5 * u.dot(&(q2 * &u));
            x = &m.a * &x + &m.b * &u;
        }
    }
    let e = &m.c * &x - r;
    j + 0.5 * e.dot(&(q1 * &e))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    /// J(z, theta) from H, F, Y equals the cost of simulating the model,
    /// for every z and theta (the condensing is exact, not just at the optimum).
    #[test]
    fn cost_equals_rollout(seed in 0u64..1000, n_h in 1usize..6, split in 0usize..3) {
        let mut rng = Rng::new(seed);
        let m = random_model(&mut rng, 3, 2, 2);
        let blocks = match split.min(n_h - 1) {
            0 => vec![n_h],
            k => { let mut v = vec![1; k]; v.push(n_h - k); v }
        };
        let q1 = rng.psd(2, 0.1);
        let q2 = rng.psd(2, 0.1);
        let settings = MpcSettings {
            horizon: n_h,
            blocking: Some(Blocking::new(blocks.clone()).unwrap()),
            q1: Weight::Matrix(q1.clone()),
            q2: Weight::Matrix(q2.clone()),
            terminal: Terminal::StageWeight,
            ..MpcSettings::default()
        };
        let bounds = Bounds::new(DVector::from_element(2, -1.0), DVector::from_element(2, 1.0));
        let prob = MpcProblem::build(&m, &MpcSettings { input_bounds: Some(bounds), ..settings }).unwrap();
        let x0 = DVector::from_fn(3, |_, _| rng.next());
        let r = DVector::from_fn(2, |_, _| rng.next());
        let z = DVector::from_fn(prob.n(), |_, _| rng.next());
        let theta = prob.theta(x0.as_slice(), r.as_slice()).unwrap();
        let j = prob.cost(&z, &theta);
        let want = rollout_cost(&m, &q1, &q2, &blocks, &x0, &r, &z);
        prop_assert!((j - want).abs() < 1e-10 * want.abs().max(1.0), "{} vs {}", j, want);
    }
}

#[test]
fn thesis_bound_structure_6_23() {
    // Tricopter bounds: E has -1 in the motor rows of the upper block and
    // +1 in the lower block, 0 for the servo; W holds the PWM limits
    // minus the trim.
    let mut rng = Rng::new(3);
    let m = random_model(&mut rng, 5, 4, 3);
    let u0 = [15.63, 0.85, -16.01, -32.3];
    let bounds = Bounds::new(
        DVector::from_fn(4, |i, _| if i < 3 { 1000.0 } else { -300.0 } - u0[i]),
        DVector::from_fn(4, |i, _| if i < 3 { 2000.0 } else { 300.0 } - u0[i]),
    )
    .shifted(DMatrix::from_column_slice(4, 1, &[-1.0, -1.0, -1.0, 0.0]));
    let settings = MpcSettings {
        horizon: 3,
        blocking: Some(Blocking::new(vec![1, 2]).unwrap()),
        terminal: Terminal::StageWeight,
        input_bounds: Some(bounds),
        parameters: vec![Parameter::new("throttle", 1000.0, 2000.0)],
        ..MpcSettings::default()
    };
    let p = MpcProblem::build(&m, &settings).unwrap();
    assert_eq!((p.n(), p.m(), p.p()), (8, 16, 9));
    let ti = 8;
    for b in 0..2 {
        for (i, u0i) in u0.iter().enumerate() {
            let k = b * 4 + i;
            let c = if i < 3 { -1.0 } else { 0.0 };
            assert_eq!(p.e[(k, ti)], c);
            assert_eq!(p.e[(8 + k, ti)], -c);
            let (lo, hi) = if i < 3 {
                (1000.0, 2000.0)
            } else {
                (-300.0, 300.0)
            };
            assert_eq!(p.w[k], hi - u0i);
            assert_eq!(p.w[8 + k], -(lo - u0i));
        }
    }
    // Only the throttle column of E is non-zero, and F's throttle row is zero.
    assert_eq!(p.e.columns(0, 8).amax(), 0.0);
    assert_eq!(p.f.row(ti).amax(), 0.0);
    // Feasible point at throttle 1500: motors 1000 - 1500 - u0 <= z <= 2000 - 1500 - u0.
    let theta = p.theta(&[0.0; 5], &[0.0, 0.0, 0.0, 1500.0]).unwrap();
    let rhs = &p.w + &p.e * &theta;
    assert!((rhs[0] - (500.0 - 15.63)).abs() < 1e-12);
    assert!((rhs[8] - (500.0 + 15.63)).abs() < 1e-12);
}

#[test]
fn bad_designs_are_clear_errors() {
    let mut rng = Rng::new(11);
    let m = random_model(&mut rng, 3, 2, 2);
    let ok = Bounds::new(
        DVector::from_element(2, -1.0),
        DVector::from_element(2, 1.0),
    );
    let base = MpcSettings {
        horizon: 3,
        terminal: Terminal::StageWeight,
        ..MpcSettings::default()
    };
    let err = |b: &Bounds, s: &MpcSettings| {
        MpcProblem::build(
            &m,
            &MpcSettings {
                input_bounds: Some(b.clone()),
                ..s.clone()
            },
        )
        .unwrap_err()
    };
    // Infeasible bounds.
    let bad = Bounds::new(
        DVector::from_vec(vec![-1.0, 2.0]),
        DVector::from_element(2, 1.0),
    );
    let e = err(&bad, &base);
    assert!(
        matches!(e, MpcError::InfeasibleBounds { input: 1, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("infeasible input bounds"));
    // Wrong bound length.
    let short = Bounds::new(
        DVector::from_element(1, -1.0),
        DVector::from_element(1, 1.0),
    );
    assert!(matches!(err(&short, &base), MpcError::Dimension { .. }));
    // NaN bound.
    let nan = Bounds::new(
        DVector::from_vec(vec![-1.0, f64::NAN]),
        DVector::from_element(2, 1.0),
    );
    assert!(matches!(err(&nan, &base), MpcError::NonFinite(_)));
    // Mismatched weight dimensions.
    let s = MpcSettings {
        q1: Weight::Matrix(DMatrix::identity(3, 3)),
        ..base.clone()
    };
    let e = err(&ok, &s);
    assert!(
        e.to_string().starts_with("Q1: expected a 2 x 2 matrix"),
        "{e}"
    );
    let s = MpcSettings {
        q2: Weight::Diagonal(vec![1.0]),
        ..base.clone()
    };
    assert!(matches!(err(&ok, &s), MpcError::Dimension { .. }));
    let s = MpcSettings {
        terminal: Terminal::State(DMatrix::identity(2, 2)),
        ..base.clone()
    };
    assert!(matches!(err(&ok, &s), MpcError::Dimension { .. }));
    // Indefinite weight.
    let s = MpcSettings {
        q1: Weight::Diagonal(vec![1.0, -1.0]),
        ..base.clone()
    };
    assert!(matches!(err(&ok, &s), MpcError::NotPositiveDefinite { .. }));
    // Non-positive-definite H: no input weight and an output weight that
    // does not see every input direction.
    let s = MpcSettings {
        q2: Weight::Scalar(0.0),
        q1: Weight::Diagonal(vec![1.0, 0.0]),
        horizon: 1,
        ..base.clone()
    };
    let e = err(&ok, &s);
    assert!(
        matches!(e, MpcError::NotPositiveDefinite { kind: "", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("Hessian H"));
    // Positive definite in exact arithmetic but not numerically: y = x,
    // x+ = 3 x + u over 14 steps puts 3^26 / 1e-4 between the largest and
    // smallest eigenvalues. The message says why a positive smallest
    // eigenvalue is refused, with the largest as computed here.
    let unstable = SsModel::new(
        0.1,
        DMatrix::from_element(1, 1, 3.0),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::from_element(1, 1, 1.0),
        DMatrix::zeros(1, 1),
    )
    .unwrap();
    let s = MpcSettings {
        horizon: 14,
        q2: Weight::Scalar(1e-4),
        terminal: Terminal::StageWeight,
        ..MpcSettings::default()
    };
    let e = MpcProblem::build(&unstable, &s).unwrap_err();
    let MpcError::NotPositiveDefinite { min_eigenvalue, .. } = &e else {
        panic!("{e}");
    };
    // The output weight sees every move, so the smallest eigenvalue is at
    // least the input weight; the largest at least H's first diagonal
    // entry, the first move's sum of 9^j over the 14 outputs it moves.
    let first_move: f64 = (0..14).map(|j| 9f64.powi(j)).sum();
    assert!(*min_eigenvalue >= 0.5e-4, "{e}");
    assert!(first_move > 1e12 * min_eigenvalue);
    let text = e.to_string();
    assert!(
        text.contains("largest eigenvalue") && text.contains("shorter horizon"),
        "{text}"
    );
    // Blocking that does not fit the horizon; zero horizon.
    let s = MpcSettings {
        blocking: Some(Blocking::new(vec![1, 1]).unwrap()),
        ..base.clone()
    };
    assert!(
        err(&ok, &s)
            .to_string()
            .contains("sum to 2, but the horizon is N = 3")
    );
    let s = MpcSettings {
        horizon: 0,
        ..base.clone()
    };
    assert!(matches!(err(&ok, &s), MpcError::InvalidSetting { .. }));
    // Feed-through and non-finite models.
    let mut md = m.clone();
    md.d[(0, 0)] = 0.5;
    assert!(matches!(
        MpcProblem::build(&md, &base),
        Err(MpcError::FeedThrough { .. })
    ));
    let mut mn = m.clone();
    mn.a[(1, 1)] = f64::INFINITY;
    assert!(matches!(
        MpcProblem::build(&mn, &base),
        Err(MpcError::NonFinite(_))
    ));
}
