//! Tests of the disturbance-augmented design ([`crate::augment`]).

use crate::testutil::Rng;
use crate::{AugmentedModel, Disturbance, DisturbanceNoise, KalmanDesign, KalmanError, NoiseModel};
use kestrel_core::StateEstimator;
use kestrel_core::formats::SsModel;
use nalgebra::{DMatrix, DVector, dmatrix, dvector};

/// A stable random plant (`nx` states) at 50 Hz with an operating point.
fn plant(seed: u64, nx: usize, nu: usize, ny: usize) -> SsModel {
    let mut rng = Rng::new(seed);
    let mut a = rng.matrix(nx, nx);
    let rho = kestrel_core::eig::spectral_radius(&a).unwrap();
    a *= 0.9 / rho;
    let b = rng.matrix(nx, nu) * 0.1;
    let c = rng.matrix(ny, nx);
    let mut m = SsModel::new(0.02, a, b, c, DMatrix::zeros(ny, nu)).unwrap();
    m.u0 = Some(DVector::from_element(nu, 0.5));
    m.y0 = Some(DVector::from_element(ny, -0.1));
    m.inputs = Some((0..nu).map(|i| format!("u{i}")).collect());
    m.outputs = Some((0..ny).map(|i| format!("y{i}")).collect());
    m
}

fn r3() -> DMatrix<f64> {
    dmatrix![
        1.30e-6, -0.02e-6, -0.06e-6;
        -0.02e-6, 7.0e-6, -0.24e-6;
        -0.06e-6, -0.24e-6, 12.67e-6
    ]
}

/// The augmentation written out by hand (the formula the offset-free MPC
/// and the pipeline's gust design used): `[A, Bd; 0, I]`, `[B; 0]`,
/// `[C, Cd]`, `D = 0`, operating point and names copied.
fn augmented_by_hand(m: &SsModel, bd: &DMatrix<f64>, cd: &DMatrix<f64>) -> SsModel {
    let (nx, nu, ny, nd) = (m.nx(), m.nu(), m.ny(), bd.ncols());
    let na = nx + nd;
    let mut a = DMatrix::identity(na, na);
    a.view_mut((0, 0), (nx, nx)).copy_from(&m.a);
    a.view_mut((0, nx), (nx, nd)).copy_from(bd);
    let mut b = DMatrix::zeros(na, nu);
    b.view_mut((0, 0), (nx, nu)).copy_from(&m.b);
    let mut c = DMatrix::zeros(ny, na);
    c.view_mut((0, 0), (ny, nx)).copy_from(&m.c);
    c.view_mut((0, nx), (ny, nd)).copy_from(cd);
    let mut aug = SsModel::new(m.ts, a, b, c, DMatrix::zeros(ny, nu)).unwrap();
    aug.u0 = m.u0.clone();
    aug.y0 = m.y0.clone();
    aug.inputs = m.inputs.clone();
    aug.outputs = m.outputs.clone();
    aug
}

/// The closed loop's former `kalman_design_with_disturbance(model, nd)`,
/// re-derived: on a model whose last `nd` states are disturbances,
/// `G = [B, C', [0; I]]`, `Q = diag(20^2 I, 0.02^2 I, 0.005^2 I)`.
fn old_closed_loop_design(model: &SsModel, nd: usize, r: DMatrix<f64>) -> KalmanDesign {
    let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
    let nw = nu + ny + nd;
    let mut g = DMatrix::zeros(nx, nw);
    g.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    g.view_mut((0, nu), (nx, ny))
        .copy_from(&model.c.transpose());
    g.view_mut((nx - nd, nu + ny), (nd, nd))
        .copy_from(&DMatrix::identity(nd, nd));
    let q = DMatrix::from_diagonal(&DVector::from_fn(nw, |i, _| {
        if i < nu {
            20.0f64.powi(2)
        } else if i < nu + ny {
            0.02f64.powi(2)
        } else {
            0.005f64.powi(2)
        }
    }));
    let noise = NoiseModel {
        g: Some(g),
        q,
        r,
        cross: None,
        bias: Some(dvector![-9.72e-4, -4.92e-5, 4.27e-3]),
    };
    KalmanDesign::new(model, &noise).unwrap()
}

fn new_closed_loop_noise(aug: &AugmentedModel, r: DMatrix<f64>) -> DisturbanceNoise {
    let mut noise = DisturbanceNoise::inputs_and_outputs(aug, 20.0, 0.02, 0.005, r);
    noise.bias = Some(dvector![-9.72e-4, -4.92e-5, 4.27e-3]);
    noise
}

#[test]
fn stationary_gain_equals_the_converged_riccati_recursion() {
    let m = plant(3, 4, 2, 3);
    for disturbance in [
        Disturbance::None,
        Disturbance::OutputStates,
        Disturbance::OutputIncrement,
        Disturbance::Input,
        Disturbance::Output,
    ] {
        let aug = AugmentedModel::new(&m, &disturbance).unwrap();
        let noise = DisturbanceNoise::inputs_and_outputs(&aug, 0.3, 0.05, 0.01, r3() * 100.0);
        let design = aug.design(&noise).unwrap();
        // Brute force: P+ = A P A' - A P C' (C P C' + R)^-1 C P A' + G Q G'
        // from P = I until it stops moving.
        let nm = aug.noise_model(&noise).unwrap();
        let g = nm.g.unwrap();
        let (a, c, r) = (&aug.model.a, &aug.model.c, &nm.r);
        let gqg = &g * &nm.q * g.transpose();
        let na = a.nrows();
        let mut p = DMatrix::<f64>::identity(na, na);
        let mut converged = false;
        for _ in 0..200_000 {
            let s = c * &p * c.transpose() + r;
            let k = &p * c.transpose() * s.try_inverse().unwrap();
            let next = a * (&p - &k * c * &p) * a.transpose() + &gqg;
            let step = (&next - &p).norm();
            p = 0.5 * (&next + next.transpose());
            if step <= 1e-15 * p.norm() {
                converged = true;
                break;
            }
        }
        assert!(converged, "{disturbance:?}: the recursion did not converge");
        let s = c * &p * c.transpose() + r;
        let m_ref = &p * c.transpose() * s.try_inverse().unwrap();
        let f = &design.kalman.filter;
        let rel = |x: &DMatrix<f64>, y: &DMatrix<f64>| (x - y).norm() / y.norm();
        assert!(
            rel(&f.p, &p) < 1e-9,
            "{disturbance:?}: P {:e}",
            rel(&f.p, &p)
        );
        assert!(
            rel(&f.m, &m_ref) < 1e-9,
            "{disturbance:?}: M {:e}",
            rel(&f.m, &m_ref)
        );
        assert_eq!(design.gain().shape(), (4 + aug.nd, 3));
        assert!(f.closed_loop_eigenvalues.iter().all(|z| z.norm() < 1.0));
    }
}

#[test]
fn maps_of_each_disturbance() {
    let mut m = plant(4, 3, 2, 2);
    m.d = dmatrix![0.1, 0.0; 0.0, -0.2];
    let maps = |d: Disturbance| d.maps(&m).unwrap();
    assert_eq!(maps(Disturbance::None).0.shape(), (3, 0));
    assert_eq!(maps(Disturbance::Input), (m.b.clone(), m.d.clone()));
    assert_eq!(
        maps(Disturbance::Output),
        (DMatrix::zeros(3, 2), DMatrix::identity(2, 2))
    );
    assert_eq!(
        maps(Disturbance::OutputStates),
        (m.c.transpose(), DMatrix::zeros(2, 2))
    );
    let (bd, cd) = maps(Disturbance::OutputIncrement);
    assert!((&m.c * bd - DMatrix::<f64>::identity(2, 2)).norm() < 1e-12);
    assert_eq!(cd, DMatrix::zeros(2, 2));
    // The augmented model keeps D and extends x0.
    m.x0 = Some(dvector![1.0, 2.0, 3.0]);
    let aug = AugmentedModel::new(&m, &Disturbance::Input).unwrap();
    assert_eq!(aug.model.d, m.d);
    assert_eq!(aug.model.c.columns(3, 2), m.d);
    assert_eq!(aug.model.x0, Some(dvector![1.0, 2.0, 3.0, 0.0, 0.0]));
    let z = [1.0, 2.0, 3.0, 4.0, 5.0];
    assert_eq!(aug.split(&z), Some((&z[..3], &z[3..])));
    assert_eq!(aug.split(&z[..4]), None);
}

#[test]
fn reproduces_the_closed_loop_filter_bit_for_bit() {
    // The offset-free closed loop: the MPC's augmented model (Bd = C', Cd = 0)
    // and the old G = [B, C', [0; I]] on it.
    let m = plant(7, 5, 4, 3);
    let old_aug = augmented_by_hand(&m, &m.c.transpose(), &DMatrix::zeros(3, 3));
    let old = old_closed_loop_design(&old_aug, 3, r3());
    let aug = AugmentedModel::new(&m, &Disturbance::OutputStates).unwrap();
    assert_eq!(aug.model, old_aug);
    let new = aug.design(&new_closed_loop_noise(&aug, r3())).unwrap();
    assert_eq!(new.kalman, old);
    assert_eq!(new.nd(), 3);
    // The same from the MPC's augmented model as it is.
    let read = AugmentedModel::from_augmented(&old_aug, 3).unwrap();
    assert_eq!((read.nx, read.nd), (5, 3));
    let new = read.design(&new_closed_loop_noise(&read, r3())).unwrap();
    assert_eq!(new.kalman, old);
    // Without disturbance states (nd = 0): G = [B, C'].
    let old = old_closed_loop_design(&m, 0, r3());
    let aug = AugmentedModel::new(&m, &Disturbance::None).unwrap();
    let new = aug.design(&new_closed_loop_noise(&aug, r3())).unwrap();
    assert_eq!(new.kalman, old);
}

#[test]
fn reproduces_the_old_formula_when_noise_enters_the_disturbance_rows() {
    // With Cd != 0 the old formula's C' column block was the augmented
    // C' = [C'; Cd'], so output noise also drove the disturbances; a
    // full-height plant_g reproduces it.
    let m = plant(8, 4, 2, 2);
    let old_aug = augmented_by_hand(&m, &DMatrix::zeros(4, 2), &DMatrix::identity(2, 2));
    let r = dmatrix![1e-4, 0.0; 0.0, 2e-4];
    let mut old_noise_g = DMatrix::zeros(6, 4);
    old_noise_g.columns_mut(0, 2).copy_from(&old_aug.b);
    old_noise_g
        .columns_mut(2, 2)
        .copy_from(&old_aug.c.transpose());
    let old = {
        let (nx, nu, ny, nd) = (6, 2, 2, 2);
        let mut g = DMatrix::zeros(nx, nu + ny + nd);
        g.columns_mut(0, nu + ny).copy_from(&old_noise_g);
        g.view_mut((nx - nd, nu + ny), (nd, nd))
            .copy_from(&DMatrix::identity(nd, nd));
        let q = DMatrix::from_diagonal(&dvector![400.0, 400.0, 4e-4, 4e-4, 2.5e-5, 2.5e-5]);
        let noise = NoiseModel {
            g: Some(g),
            q,
            r: r.clone(),
            cross: None,
            bias: None,
        };
        KalmanDesign::new(&old_aug, &noise).unwrap()
    };
    let aug = AugmentedModel::new(&m, &Disturbance::Output).unwrap();
    let mut noise = DisturbanceNoise::inputs_and_outputs(&aug, 20.0, 0.02, 0.005, r);
    noise.plant_g = old_noise_g;
    assert_eq!(aug.design(&noise).unwrap().kalman, old);
}

#[test]
fn reproduces_the_gust_design_bit_for_bit() {
    // The pipeline's former gust design: Bd = pinv(C) (tolerance 1e-12),
    // G = [B, C', 0; 0, 0, I], Q = diag(input^2, rate^2, gust^2).
    let m = plant(9, 5, 4, 3);
    let (input, rate, gust) = (20.0, 0.03, 0.002);
    let bd = m.c.clone().pseudo_inverse(1e-12).unwrap();
    let old_aug = augmented_by_hand(&m, &bd, &DMatrix::zeros(3, 3));
    let (nx, nu, ny) = (5, 4, 3);
    let nw = nu + 2 * ny;
    let mut g = DMatrix::zeros(nx + ny, nw);
    g.view_mut((0, 0), (nx, nu)).copy_from(&m.b);
    g.view_mut((0, nu), (nx, ny)).copy_from(&m.c.transpose());
    g.view_mut((nx, nu + ny), (ny, ny))
        .copy_from(&DMatrix::identity(ny, ny));
    let q = DMatrix::from_diagonal(&DVector::from_fn(nw, |i, _| {
        if i < nu {
            input * input
        } else if i < nu + ny {
            rate * rate
        } else {
            gust * gust
        }
    }));
    let bias = dvector![0.01, -0.02, 0.003];
    let old = KalmanDesign::new(
        &old_aug,
        &NoiseModel {
            g: Some(g),
            q,
            r: r3(),
            cross: None,
            bias: Some(bias.clone()),
        },
    )
    .unwrap();
    let aug = AugmentedModel::new(&m, &Disturbance::OutputIncrement).unwrap();
    let mut noise = DisturbanceNoise::inputs_and_outputs(&aug, input, rate, gust, r3());
    noise.bias = Some(bias);
    assert_eq!(aug.design(&noise).unwrap().kalman, old);
}

#[test]
fn the_filter_estimates_a_constant_input_disturbance() {
    // Plant with an input bias of 0.4, measured without noise: the
    // disturbance state converges to the bias, the plant state to x.
    let plant = SsModel::new(
        0.1,
        dmatrix![0.9, 0.1; 0.0, 0.8],
        dmatrix![0.0; 0.2],
        dmatrix![1.0, 0.0],
        dmatrix![0.0],
    )
    .unwrap();
    let aug = AugmentedModel::new(&plant, &Disturbance::Input).unwrap();
    let noise = DisturbanceNoise::inputs_and_outputs(&aug, 0.01, 0.01, 0.01, dmatrix![1e-4]);
    let design = aug.design(&noise).unwrap();
    let mut filter = design.kalman.filter::<f64, 3, 1, 1>().unwrap();
    let mut x = dvector![0.0, 0.0];
    for k in 0..400 {
        let u = (0.1 * k as f64).sin();
        let y = (&plant.c * &x)[0];
        filter.measurement_update(&[y]).unwrap();
        filter.time_update(&[u]).unwrap();
        x = &plant.a * &x + &plant.b * (u + 0.4);
    }
    let z = filter.estimate();
    assert!((z[2] - 0.4).abs() < 1e-3, "disturbance estimate {}", z[2]);
    assert!((z[0] - x[0]).abs() < 1e-3 && (z[1] - x[1]).abs() < 1e-3);
}

#[test]
fn undetectable_disturbances_are_refused() {
    // An integrator with an output offset cannot tell d from x.
    let integrator = SsModel::new(
        0.1,
        dmatrix![1.0],
        dmatrix![0.1],
        dmatrix![1.0],
        dmatrix![0.0],
    )
    .unwrap();
    let e = AugmentedModel::new(&integrator, &Disturbance::Output).unwrap_err();
    assert_eq!(
        e,
        KalmanError::DisturbanceNotDetectable {
            rank: 1,
            required: 2
        }
    );
    assert!(e.to_string().contains("not detectable"), "{e}");
    // More disturbances than outputs: two input disturbances, one output.
    let m = plant(11, 3, 2, 1);
    let e = AugmentedModel::new(&m, &Disturbance::Input).unwrap_err();
    assert!(matches!(
        e,
        KalmanError::DisturbanceNotDetectable {
            rank: 4,
            required: 5
        }
    ));
    // The same check on an already augmented model.
    let aug = augmented_by_hand(&integrator, &DMatrix::zeros(1, 1), &DMatrix::identity(1, 1));
    assert!(matches!(
        AugmentedModel::from_augmented(&aug, 1),
        Err(KalmanError::DisturbanceNotDetectable { .. })
    ));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let m = plant(12, 3, 2, 2);
    let custom = |bd: DMatrix<f64>, cd: DMatrix<f64>| {
        AugmentedModel::new(&m, &Disturbance::Custom { bd, cd }).unwrap_err()
    };
    assert!(matches!(
        custom(DMatrix::zeros(2, 1), DMatrix::zeros(2, 1)),
        KalmanError::DimensionMismatch { name: "Bd", .. }
    ));
    assert!(matches!(
        custom(DMatrix::zeros(3, 1), DMatrix::zeros(2, 2)),
        KalmanError::DimensionMismatch { name: "Cd", .. }
    ));
    let mut bd = DMatrix::zeros(3, 1);
    bd[(1, 0)] = f64::NAN;
    assert!(matches!(
        custom(bd, DMatrix::zeros(2, 1)),
        KalmanError::NonFinite {
            name: "Bd",
            row: 1,
            col: 0
        }
    ));
    // A plant with NaN, inconsistent matrices, or in continuous time.
    let mut bad = m.clone();
    bad.a[(0, 0)] = f64::NAN;
    assert!(matches!(
        AugmentedModel::new(&bad, &Disturbance::OutputStates),
        Err(KalmanError::NonFinite { name: "A", .. })
    ));
    let mut bad = m.clone();
    bad.d = DMatrix::zeros(2, 3);
    assert!(matches!(
        AugmentedModel::new(&bad, &Disturbance::OutputStates),
        Err(KalmanError::DimensionMismatch { name: "D", .. })
    ));
    let mut bad = m.clone();
    bad.ts = 0.0;
    assert!(matches!(
        AugmentedModel::new(&bad, &Disturbance::OutputStates),
        Err(KalmanError::InvalidArgument { name: "ts", .. })
    ));
    // Noise blocks that do not fit, or hold NaN.
    let aug = AugmentedModel::new(&m, &Disturbance::OutputStates).unwrap();
    let good = DisturbanceNoise::inputs_and_outputs(&aug, 0.1, 0.1, 0.01, DMatrix::identity(2, 2));
    let check = |edit: &dyn Fn(&mut DisturbanceNoise), name: &str| {
        let mut noise = good.clone();
        edit(&mut noise);
        match aug.design(&noise) {
            Err(KalmanError::DimensionMismatch { name: n, .. })
            | Err(KalmanError::NonFinite { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: expected a shape or NaN error, got {other:?}"),
        }
    };
    check(&|n| n.plant_g = DMatrix::zeros(4, 4), "plant_g");
    check(&|n| n.plant_q = DMatrix::identity(3, 3), "plant_q");
    check(
        &|n| n.disturbance_q = DMatrix::identity(1, 1),
        "disturbance_q",
    );
    check(&|n| n.r[(1, 1)] = f64::NAN, "R");
    check(&|n| n.bias = Some(dvector![0.0, 0.0, 0.0]), "bias");
    check(&|n| n.plant_q[(0, 0)] = f64::INFINITY, "plant_q");
    // An indefinite covariance is refused by the design.
    let mut noise = good.clone();
    noise.disturbance_q[(0, 0)] = -1.0;
    assert!(matches!(
        aug.design(&noise),
        Err(KalmanError::NotPositiveSemidefinite { .. })
    ));
    // An augmented model whose last states are not integrators.
    assert!(matches!(
        AugmentedModel::from_augmented(&m, 1),
        Err(KalmanError::InvalidArgument { name: "model", .. })
    ));
    assert!(matches!(
        AugmentedModel::from_augmented(&m, 4),
        Err(KalmanError::InvalidArgument { name: "nd", .. })
    ));
}

#[test]
fn empty_plants_are_errors_or_designs_not_panics() {
    // No states and no outputs: two disturbances nobody sees.
    let none = SsModel::new(
        0.1,
        DMatrix::zeros(0, 0),
        DMatrix::zeros(0, 1),
        DMatrix::zeros(0, 0),
        DMatrix::zeros(0, 1),
    )
    .unwrap();
    let custom = Disturbance::Custom {
        bd: DMatrix::zeros(0, 2),
        cd: DMatrix::zeros(0, 2),
    };
    assert_eq!(
        AugmentedModel::new(&none, &custom).unwrap_err(),
        KalmanError::DisturbanceNotDetectable {
            rank: 0,
            required: 2
        }
    );
    // No states, two outputs: output offsets are measured directly, a
    // state increment has no state to enter.
    let outputs = SsModel::new(
        0.1,
        DMatrix::zeros(0, 0),
        DMatrix::zeros(0, 1),
        DMatrix::zeros(2, 0),
        DMatrix::zeros(2, 1),
    )
    .unwrap();
    let aug = AugmentedModel::new(&outputs, &Disturbance::Output).unwrap();
    assert_eq!(
        (aug.nx, aug.nd, aug.model.c.clone()),
        (0, 2, DMatrix::identity(2, 2))
    );
    assert!(matches!(
        AugmentedModel::new(&outputs, &Disturbance::OutputIncrement),
        Err(KalmanError::DisturbanceNotDetectable {
            rank: 0,
            required: 2
        })
    ));
}
