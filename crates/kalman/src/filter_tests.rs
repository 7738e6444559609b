//! Tests of the stationary (run-time) and time-varying filters.

use crate::testutil::Rng;
use crate::{KalmanDesign, NoiseModel, StationaryFilter, TimeVaryingFilter};
use kestrel_core::formats::SsModel;
use kestrel_core::{Error, Q16, Scalar, StateEstimator};
use nalgebra::{DMatrix, DVector, dmatrix, dvector};

/// Gyro bias (7.5) and measurement covariance (7.6) of the thesis.
fn thesis_bias() -> DVector<f64> {
    dvector![-9.72e-4, -4.92e-5, 4.27e-3]
}
fn thesis_r() -> DMatrix<f64> {
    dmatrix![
        1.30e-6, -0.02e-6, -0.06e-6;
        -0.02e-6, 7.0e-6, -0.24e-6;
        -0.06e-6, -0.24e-6, 12.67e-6
    ]
}

/// A stable 5-state, 4-input, 3-output model at 50 Hz with an operating
/// point (the size of the thesis's black-box model; test-local, random).
fn model_5_4_3(seed: u64) -> SsModel {
    let mut rng = Rng::new(seed);
    let mut a = rng.matrix(5, 5) * (0.95 / 5f64.sqrt());
    let rho = kestrel_core::eig::spectral_radius(&a).unwrap();
    a *= 0.97 / rho;
    let b = rng.matrix(5, 4) * 0.05;
    let c = rng.matrix(3, 5) * 0.5;
    let mut m = SsModel::new(0.02, a, b, c, DMatrix::zeros(3, 4)).unwrap();
    m.u0 = Some(dvector![15.63, 0.85, -16.01, 1467.7] * 0.01);
    m.y0 = Some(dvector![0.01, -0.02, 0.005]);
    m
}

fn design(model: &SsModel) -> KalmanDesign {
    let noise = NoiseModel {
        g: None,
        q: DMatrix::identity(5, 5) * 1e-4,
        r: thesis_r(),
        cross: None,
        bias: Some(thesis_bias()),
    };
    KalmanDesign::new(model, &noise).unwrap()
}

/// A simulated log: inputs (absolute) and measurements (absolute, with bias and noise).
struct Log {
    u: Vec<[f64; 4]>,
    y: Vec<[f64; 3]>,
    x: Vec<DVector<f64>>,
}

fn simulate(model: &SsModel, steps: usize, seed: u64) -> Log {
    let mut rng = Rng::new(seed);
    let r_chol = thesis_r().cholesky().unwrap().l();
    let u0 = model.u0.clone().unwrap();
    let y0 = model.y0.clone().unwrap();
    let bias = thesis_bias();
    let mut x = DVector::zeros(5);
    let mut log = Log {
        u: Vec::new(),
        y: Vec::new(),
        x: Vec::new(),
    };
    for k in 0..steps {
        let t = k as f64 * model.ts;
        let du = dvector![
            (2.0 * t).sin() + 0.3 * rng.normal(),
            (3.1 * t).cos(),
            if (k / 150) % 2 == 0 { 0.8 } else { -0.8 },
            0.5 * (0.7 * t).sin()
        ];
        let v = &r_chol * DVector::from_fn(3, |_, _| rng.normal());
        let y = &model.c * &x + &y0 + &bias + v;
        log.y.push([y[0], y[1], y[2]]);
        let u = &du + &u0;
        log.u.push([u[0], u[1], u[2], u[3]]);
        log.x.push(x.clone());
        let w = DVector::from_fn(5, |_, _| 1e-2 * rng.normal());
        x = &model.a * &x + &model.b * du + w;
    }
    log
}

/// Runs a run-time filter over the log; returns the filtered estimates in f64.
fn run<S: Scalar>(f: &mut StationaryFilter<S, 5, 4, 3>, log: &Log) -> Vec<[f64; 5]> {
    let mut out = Vec::with_capacity(log.y.len());
    for (y, u) in log.y.iter().zip(&log.u) {
        let ys: [S; 3] = core::array::from_fn(|i| S::from_f64(y[i]));
        f.update(&ys).unwrap();
        out.push(core::array::from_fn(|i| f.state()[i].to_f64()));
        let us: [S; 4] = core::array::from_fn(|i| S::from_f64(u[i]));
        f.predict(&us).unwrap();
    }
    out
}

#[test]
fn thesis_size_costs_75_multiply_adds() {
    let d = design(&model_5_4_3(1));
    let g = d.gains::<f64, 5, 4, 3>().unwrap();
    assert!(!g.use_cross && !g.use_d);
    assert_eq!(g.multiply_adds(), 3 * 5 + 5 * 3 + 5 * 5 + 5 * 4);
    assert_eq!(g.multiply_adds(), 75);
    // The design-time count (no const dimensions) and the file agree.
    assert_eq!(d.multiply_adds(), 75);
    assert_eq!(d.to_object()["multiply_adds"], serde_json::json!(75));
    // Wrong const dimensions are an error, not a panic.
    assert!(d.gains::<f64, 4, 4, 3>().is_err());
    assert!(d.gains::<f64, 5, 3, 3>().is_err());
}

#[test]
fn stationary_matches_converged_time_varying_filter() {
    let model = model_5_4_3(2);
    let d = design(&model);
    let log = simulate(&model, 1500, 3);
    let mut fs = d.filter::<f64, 5, 4, 3>().unwrap();
    let mut tv = TimeVaryingFilter::from_design(&d, d.filter.p.clone() * 50.0).unwrap();
    let mut max_late = 0.0f64;
    for (k, (y, u)) in log.y.iter().zip(&log.u).enumerate() {
        fs.update(y).unwrap();
        tv.measurement_update(y).unwrap();
        if k > 1000 {
            let diff = (DVector::from_column_slice(fs.state()) - &tv.x).amax();
            max_late = max_late.max(diff);
        }
        fs.predict(u).unwrap();
        tv.time_update(u).unwrap();
    }
    // The Riccati difference equation converged to the DARE solution ...
    assert!((&tv.p - &d.filter.p).norm() < 1e-9 * d.filter.p.norm());
    assert!((&tv.gain - &d.filter.m).norm() < 1e-9 * d.filter.m.norm());
    // ... so both filters give the same estimates.
    assert!(max_late < 1e-9, "max difference {max_late:e}");
}

#[test]
fn filter_beats_the_raw_measurement_on_simulated_data() {
    let model = model_5_4_3(4);
    let d = design(&model);
    let log = simulate(&model, 3000, 5);
    let mut f = d.filter::<f64, 5, 4, 3>().unwrap();
    let (mut err_filter, mut err_raw) = (0.0, 0.0);
    let y0 = model.y0.clone().unwrap();
    for (k, (y, u)) in log.y.iter().zip(&log.u).enumerate() {
        f.update(y).unwrap();
        if k > 100 {
            let truth = &model.c * &log.x[k] + &y0;
            let est = f.output_estimate();
            for i in 0..3 {
                err_filter += (est[i] - truth[i]).powi(2);
                // The raw gyro carries the bias and the noise.
                err_raw += (y[i] - truth[i]).powi(2);
            }
        }
        f.predict(u).unwrap();
    }
    assert!(err_filter < 0.5 * err_raw, "{err_filter} vs {err_raw}");
}

/// The error between a filter in scalar `S` and in f64 obeys
/// `e+ = F e + xi`, `F = (I - M C) A`, with `xi` bounded by the format's
/// resolution times the magnitudes of the signals (coefficient rounding
/// plus arithmetic rounding); the bound is `sum_k ||F^k||_inf * max |xi|`.
fn error_bound(d: &KalmanDesign, resolution: f64, xmax: f64, umax: f64, ymax: f64) -> f64 {
    let f = (DMatrix::identity(5, 5) - &d.filter.m * &d.c) * &d.a;
    let inf_norm = |m: &DMatrix<f64>| {
        m.row_iter()
            .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    };
    let mut amp = 0.0;
    let mut fk = DMatrix::identity(5, 5);
    for _ in 0..2000 {
        let n = inf_norm(&fk);
        amp += n;
        if n < 1e-9 {
            break;
        }
        fk = &f * fk;
    }
    let mn = inf_norm(&d.filter.m).max(1.0);
    let emax = ymax + inf_norm(&d.c) * xmax;
    // Per entry: coefficients and data are rounded to half a resolution
    // step (relative for floats: scaled by the magnitudes below), and each
    // dot product and sum rounds once more.
    let xi = resolution
        * ((5.0 + 1.0) * xmax * (1.0 + mn)
            + (4.0 + 1.0) * umax * (1.0 + inf_norm(&d.b))
            + (3.0 + 1.0) * emax * (1.0 + mn)
            + 4.0);
    amp * xi
}

#[test]
fn f32_and_q16_match_f64_over_10000_steps() {
    let model = model_5_4_3(6);
    let d = design(&model);
    let log = simulate(&model, 10_000, 7);
    let ref64 = run(&mut d.filter::<f64, 5, 4, 3>().unwrap(), &log);
    let est32 = run(&mut d.filter::<f32, 5, 4, 3>().unwrap(), &log);
    let estq = run(&mut d.filter::<Q16, 5, 4, 3>().unwrap(), &log);
    let xmax = ref64.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let umax = log.u.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let ymax = log.y.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let max_diff = |est: &[[f64; 5]]| {
        est.iter()
            .zip(&ref64)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
            .fold(0.0f64, f64::max)
    };
    let (e32, eq) = (max_diff(&est32), max_diff(&estq));
    let b32 = error_bound(&d, f32::RESOLUTION, xmax, umax, ymax);
    let bq = error_bound(&d, Q16::RESOLUTION, xmax, umax, ymax);
    println!(
        "xmax {xmax:.3}: f32 error {e32:.2e} (bound {b32:.2e}), Q16 error {eq:.2e} (bound {bq:.2e})"
    );
    assert!(e32 <= b32, "f32: {e32:e} > {b32:e}");
    assert!(eq <= bq, "Q16: {eq:e} > {bq:e}");
    // The bounds are far below the signal ...
    assert!(
        b32 < 1e-3 * xmax && bq < 5e-2 * xmax,
        "{b32:e} {bq:e} {xmax}"
    );
    // ... and the errors are in fact a few units of the format's precision
    // per unit of the largest state (the rounding of the coefficients is
    // multiplied by the state; measured: about 1 f32 ulp of the largest
    // state, 4 Q16 LSBs per unit of it, at xmax = 10.2).
    assert!(e32 <= 16.0 * f32::RESOLUTION * xmax, "f32: {e32:e}");
    assert!(eq <= 16.0 * Q16::RESOLUTION * xmax.max(1.0), "Q16: {eq:e}");
    // And the formats really differ from f64 (the comparison is not vacuous).
    assert!(e32 > 0.0 && eq > e32);
}

#[test]
fn non_finite_measurement_keeps_the_prediction() {
    let model = model_5_4_3(8);
    let d = design(&model);
    let log = simulate(&model, 400, 9);
    let mut f = d.filter::<f64, 5, 4, 3>().unwrap();
    let mut reference = d.filter::<f64, 5, 4, 3>().unwrap();
    let mut rejected = 0;
    for (k, (y, u)) in log.y.iter().zip(&log.u).enumerate() {
        let mut y_bad = *y;
        let bad = k % 37 == 5;
        if bad {
            y_bad[k % 3] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][k % 3];
        }
        let before = *f.state();
        let r = f.update(&y_bad);
        if bad {
            rejected += 1;
            assert_eq!(r, Err(Error::NonFinite));
            assert_eq!(f.state(), &before, "estimate kept at the prediction");
            assert!(f.status().last_rejected);
        } else {
            r.unwrap();
            reference.update(y).unwrap();
            assert!(!f.status().last_rejected);
        }
        assert!(f.state().iter().all(|v| v.is_finite()));
        f.predict(u).unwrap();
        reference.predict(u).unwrap();
    }
    assert_eq!(f.status().rejected, rejected);
    // A huge (finite) measurement that overflows is also refused.
    let before = *f.state();
    assert_eq!(
        f.update(&[f64::MAX, f64::MAX, f64::MAX]),
        Err(Error::NonFinite)
    );
    assert_eq!(f.state(), &before);
    // A non-finite input is refused too.
    assert_eq!(f.predict(&[f64::NAN, 0.0, 0.0, 0.0]), Err(Error::NonFinite));
    assert_eq!(f.state(), &before);
    assert_eq!(f.status().rejected_inputs, 1);
    // The same for the time-varying filter.
    let mut tv = TimeVaryingFilter::from_design(&d, d.filter.p.clone()).unwrap();
    let x = tv.x.clone();
    assert_eq!(
        tv.measurement_update(&[f64::NAN, 0.0, 0.0]),
        Err(Error::NonFinite)
    );
    assert_eq!(tv.x, x);
    assert_eq!(tv.rejected(), 1);
}

#[test]
fn operating_point_and_bias_are_removed() {
    // The filter on absolute signals equals the filter on deviation
    // signals with a zero operating point and no bias.
    let model = model_5_4_3(10);
    let d = design(&model);
    let mut dev_model = model.clone();
    dev_model.u0 = None;
    dev_model.y0 = None;
    let d_dev = KalmanDesign::new(
        &dev_model,
        &NoiseModel {
            bias: None,
            ..NoiseModel {
                g: None,
                q: d.q.clone(),
                r: d.r.clone(),
                cross: None,
                bias: None,
            }
        },
    )
    .unwrap();
    let log = simulate(&model, 500, 11);
    let mut f = d.filter::<f64, 5, 4, 3>().unwrap();
    let mut g = d_dev.filter::<f64, 5, 4, 3>().unwrap();
    let u0 = model.u0.clone().unwrap();
    let off = model.y0.clone().unwrap() + thesis_bias();
    for (y, u) in log.y.iter().zip(&log.u) {
        f.update(y).unwrap();
        g.update(&core::array::from_fn(|i| y[i] - off[i])).unwrap();
        let diff =
            (DVector::from_column_slice(f.state()) - DVector::from_column_slice(g.state())).amax();
        assert!(diff < 1e-12, "{diff:e}");
        f.predict(u).unwrap();
        g.predict(&core::array::from_fn(|i| u[i] - u0[i])).unwrap();
    }
    // Ignoring the bias gives a visibly biased output estimate.
    let mut h = d_dev.filter::<f64, 5, 4, 3>().unwrap();
    let y0 = model.y0.clone().unwrap();
    let mut mean_err = [0.0; 3];
    for (k, (y, u)) in log.y.iter().zip(&log.u).enumerate() {
        h.update(&core::array::from_fn(|i| y[i] - y0[i])).unwrap();
        let truth = &model.c * &log.x[k];
        for i in 0..3 {
            mean_err[i] += (h.output_estimate()[i] - truth[i]) / log.y.len() as f64;
        }
        h.predict(&core::array::from_fn(|i| u[i] - u0[i])).unwrap();
    }
    assert!(
        (mean_err[2] - thesis_bias()[2]).abs() < 0.5 * thesis_bias()[2].abs(),
        "{mean_err:?}"
    );
}

/// An identified model in innovations form (`x+ = A x + B du + K e`,
/// `y = C x + y0 + e`): the filter of [`NoiseModel::innovations`] is the
/// model's own predictor, `L = K`, `P = 0`, `M = 0`, for any innovation
/// covariance; run on data simulated from that model from its true initial
/// state, the run-time filter's prediction is the true state and its
/// innovations are the simulated `e`.
#[test]
fn innovations_form_gives_the_models_own_predictor() {
    let model = model_5_4_3(21);
    let mut rng = Rng::new(22);
    // A gain with A - K C stable.
    let mut k = rng.matrix(5, 3);
    let rho =
        |k: &DMatrix<f64>| kestrel_core::eig::spectral_radius(&(&model.a - k * &model.c)).unwrap();
    while rho(&k) >= 0.99 {
        k *= 0.7;
    }
    assert!(k.amax() > 1e-3);
    let re = rng.spd(3, 10.0) * 1e-4;
    let d = KalmanDesign::new(&model, &NoiseModel::innovations(&k, &re)).unwrap();
    assert!(
        (&d.filter.l - &k).amax() < 1e-9 * k.amax(),
        "{}",
        &d.filter.l - &k
    );
    assert!(d.filter.m.amax() < 1e-9 * k.amax(), "{}", d.filter.m);
    assert!(d.filter.p.amax() < 1e-12, "{}", d.filter.p);
    // The gain does not depend on the innovation covariance.
    let other =
        KalmanDesign::new(&model, &NoiseModel::innovations(&k, &(re.clone() * 1e4))).unwrap();
    assert!((&other.filter.l - &k).amax() < 1e-9 * k.amax());

    let mut f = StationaryFilter::new(d.gains::<f64, 5, 4, 3>().unwrap(), [0.0; 5]);
    let chol = re.cholesky().unwrap().l();
    let (u0, y0) = (model.u0.clone().unwrap(), model.y0.clone().unwrap());
    let mut x = DVector::<f64>::zeros(5);
    for step in 0..300 {
        let du = dvector![(0.1 * step as f64).sin(), 0.3, -0.2, rng.normal()];
        let e = &chol * DVector::from_fn(3, |_, _| rng.normal());
        let y = &model.c * &x + &y0 + &e;
        let u = &du + &u0;
        // Before the update the filter holds its prediction: the true state.
        let gap = (DVector::from_column_slice(f.state()) - &x).amax();
        assert!(gap < 1e-9, "step {step}: state error {gap:e}");
        let innovation = &y - &y0 - &model.c * DVector::from_column_slice(f.state());
        assert!((&innovation - &e).amax() < 1e-9);
        f.update(&[y[0], y[1], y[2]]).unwrap();
        f.predict(&[u[0], u[1], u[2], u[3]]).unwrap();
        x = &model.a * &x + &model.b * du + &k * e;
    }
}

/// An innovations model whose predictor `A - K C` is unstable (eigenvalues
/// about 1.519 and 0.981 here) has no filter with the noise it states: the
/// design names the unstable mode of `A - K C`.
#[test]
fn innovations_form_with_an_unstable_predictor_is_refused() {
    let model = SsModel::new(
        0.02,
        dmatrix![1.0, 0.02; 0.0, 1.0],
        dmatrix![0.0002; 0.02],
        dmatrix![1.0, 0.0],
        dmatrix![0.0],
    )
    .unwrap();
    let k = dmatrix![-0.5; -0.5];
    let e = KalmanDesign::new(&model, &NoiseModel::innovations(&k, &dmatrix![1.0])).unwrap_err();
    // A - K C = [1.5, 0.02; 0.5, 1]: 1.25 + sqrt(0.0725).
    let unstable = 1.25 + 0.0725f64.sqrt();
    match e {
        crate::KalmanError::NotStabilizable { eigenvalue } => {
            assert!(
                (eigenvalue.re - unstable).abs() < 1e-9 && eigenvalue.im == 0.0,
                "{eigenvalue}"
            )
        }
        other => panic!("{other}"),
    }
}

#[test]
fn cross_covariance_uses_the_predictor_gain() {
    // Correlated noise: the time update adds (L - A M) e; the filter then
    // reproduces the predictor x+ = A x + B du + L e of python-control.
    let model = model_5_4_3(12);
    let mut rng = Rng::new(13);
    let noise = NoiseModel {
        g: None,
        q: DMatrix::identity(5, 5) * 1e-3,
        r: thesis_r(),
        cross: Some(rng.matrix(5, 3) * 1e-6),
        bias: None,
    };
    let d = KalmanDesign::new(&model, &noise).unwrap();
    let g = d.gains::<f64, 5, 4, 3>().unwrap();
    assert!(g.use_cross);
    assert_eq!(g.multiply_adds(), 75 + 15);
    assert_eq!(d.multiply_adds(), 75 + 15);
    let mut f = StationaryFilter::new(g, [0.0; 5]);
    let log = simulate(&model, 200, 14);
    let mut xp = DVector::<f64>::zeros(5);
    let u0 = model.u0.clone().unwrap();
    let off = model.y0.clone().unwrap();
    for (y, u) in log.y.iter().zip(&log.u) {
        let e = DVector::from_column_slice(y) - &off - &d.c * &xp;
        f.update(y).unwrap();
        f.predict(u).unwrap();
        xp = &d.a * &xp + &d.b * (DVector::from_column_slice(u) - &u0) + &d.filter.l * e;
        let diff = (DVector::from_column_slice(f.state()) - &xp).amax();
        assert!(diff < 1e-12, "{diff:e}");
    }
}

#[test]
fn trait_checks_lengths() {
    let d = design(&model_5_4_3(15));
    let mut f = d.filter::<f64, 5, 4, 3>().unwrap();
    assert_eq!(
        f.measurement_update(&[0.0; 2]),
        Err(Error::DimensionMismatch {
            expected: 3,
            found: 2
        })
    );
    assert!(f.time_update(&[0.0; 5]).is_err());
    assert!(f.reset(&[0.0; 4]).is_err());
    assert_eq!(f.reset(&[f64::NAN; 5]), Err(Error::NonFinite));
    f.reset(&[1.0; 5]).unwrap();
    assert_eq!(f.estimate(), &[1.0; 5]);
    assert_eq!((f.nx(), f.nu(), f.ny()), (5, 4, 3));
    let mut tv = TimeVaryingFilter::from_design(&d, DMatrix::identity(5, 5)).unwrap();
    assert!(tv.measurement_update(&[0.0; 4]).is_err());
    assert!(tv.time_update(&[0.0; 3]).is_err());
}

#[test]
fn design_rejects_bad_input() {
    let model = model_5_4_3(16);
    let mut noise = NoiseModel::isotropic(5, 3, 1e-4, 1e-4);
    noise.bias = Some(dvector![0.0, 0.0]);
    assert!(KalmanDesign::new(&model, &noise).is_err());
    let noise = NoiseModel::isotropic(5, 2, 1e-4, 1e-4);
    assert!(KalmanDesign::new(&model, &noise).is_err());
    let mut cont = model.clone();
    cont.ts = 0.0;
    let err = KalmanDesign::new(&cont, &NoiseModel::isotropic(5, 3, 1e-4, 1e-4)).unwrap_err();
    assert!(err.to_string().contains("discrete"), "{err}");
    // kestrel.kalman.v1 round trip and a corrupted file.
    let d = design(&model);
    let text = d.to_json_string();
    let back = KalmanDesign::from_json_str(&text).unwrap();
    // serde_json's default float parser may be one ulp off.
    assert!((&back.filter.m - &d.filter.m).amax() <= 1e-15 * d.filter.m.amax());
    assert!((&back.filter.p - &d.filter.p).amax() <= 1e-15 * d.filter.p.amax());
    assert!((&back.bias - &d.bias).amax() <= 1e-15);
    let broken = text.replacen("\"M\"", "\"M_\"", 1);
    let err = KalmanDesign::from_json_str(&broken).unwrap_err();
    assert!(err.to_string().contains("\"M\""), "{err}");
    let wrong = text.replacen("kestrel.kalman.v1", "kestrel.ss.v1", 1);
    assert!(KalmanDesign::from_json_str(&wrong).is_err());
}
