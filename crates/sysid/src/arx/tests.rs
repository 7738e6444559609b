use super::*;
use crate::data::IoData;
use crate::error::{SizedMethod, SysidError};
use crate::linalg::lstsq;
use crate::synthetic::{self, Rng};
use crate::validate::{fit_percent, predict_fit};
use nalgebra::DMatrix;

/// A stable 2-output, 2-input ARX model (na = 2, nb = 2, nk = 1).
fn truth() -> ArxModel {
    let a = vec![
        DMatrix::from_row_slice(2, 2, &[0.6, 0.1, -0.2, 0.5]),
        DMatrix::from_row_slice(2, 2, &[-0.2, 0.05, 0.1, -0.1]),
    ];
    let b = vec![
        DMatrix::from_row_slice(2, 2, &[1.0, 0.3, 0.0, -0.7]),
        DMatrix::from_row_slice(2, 2, &[0.4, 0.0, 0.2, 0.5]),
    ];
    ArxModel::new(0.02, ArxSettings::lags(2), 2, 2, a, b).unwrap()
}

/// Data of `m` driven by white inputs and white noise of std `noise`.
fn simulate_arx(m: &ArxModel, n: usize, noise: f64, seed: u64) -> IoData {
    let mut rng = Rng::new(seed);
    let u = rng.normal_matrix(n, m.nu());
    let mut y = DMatrix::zeros(n, m.ny());
    for t in 0..n {
        let mut v = rng.normal_matrix(m.ny(), 1) * noise;
        for (i, ai) in m.a().iter().enumerate() {
            if t > i {
                v += ai * y.row(t - 1 - i).transpose();
            }
        }
        for (j, bj) in m.b().iter().enumerate() {
            let lag = m.settings().nk + j;
            if t >= lag {
                v += bj * u.row(t - lag).transpose();
            }
        }
        y.row_mut(t).copy_from(&v.transpose());
    }
    IoData::new(m.ts(), u, y).unwrap()
}

#[test]
fn recovers_a_known_arx_model() {
    let t = truth();
    let data = simulate_arx(&t, 20_000, 0.1, 1);
    let m = arx(&data, &ArxSettings::lags(2)).unwrap();
    for (x, y) in m.a().iter().zip(t.a()).chain(m.b().iter().zip(t.b())) {
        assert!((x - y).amax() < 0.01, "{x} vs {y}");
    }
    // The residual covariance is the noise's, 0.01 I.
    let lam = m.noise_covariance();
    assert!(
        (lam - DMatrix::identity(2, 2) * 0.01).amax() < 1e-3,
        "{lam}"
    );
}

#[test]
fn normal_equations_agree_with_an_svd_least_squares_solve() {
    // Coloured data, extra lags and a feed-through: a less trivial regression.
    let truth = synthetic::random_model(4, 3, 2, 11, 0.95);
    let data = synthetic::simulate(&truth, 1500, 0.3, 4).unwrap();
    let s = ArxSettings {
        na: 3,
        nb: 4,
        nk: 0,
    };
    let m = arx(&data, &s).unwrap();
    // The full regression matrix, unscaled, solved by the SVD.
    let e = &data.experiments()[0];
    let lag = s.max_lag();
    let p = s.parameters_per_output(3, 2);
    let rows = e.len() - lag;
    let mut phi = DMatrix::zeros(rows, p);
    let mut row = vec![0.0; p];
    for r in 0..rows {
        estimate::regressor(&s, &e.u, &e.y, lag + r, &mut row);
        for (j, v) in row.iter().enumerate() {
            phi[(r, j)] = *v;
        }
    }
    let yt = e.y.rows(lag, rows).into_owned();
    let theta = lstsq(&phi, &yt).transpose(); // ny x p
    let mut c = 0;
    for ai in m.a() {
        assert!((ai - theta.columns(c, 2)).amax() < 1e-9);
        c += 2;
    }
    for bj in m.b() {
        assert!((bj - theta.columns(c, 3)).amax() < 1e-9);
        c += 3;
    }
    let resid = &yt - &phi * theta.transpose();
    let lam = resid.tr_mul(&resid) / rows as f64;
    assert!((m.noise_covariance() - lam).amax() < 1e-9);
}

#[test]
fn k_step_predictions_equal_those_of_the_realisation() {
    let truth = synthetic::random_model(3, 2, 3, 7, 0.9);
    let data = synthetic::simulate(&truth, 600, 0.2, 9).unwrap();
    for s in [
        ArxSettings::lags(3),
        ArxSettings {
            na: 1,
            nb: 3,
            nk: 2,
        },
        ArxSettings {
            na: 4,
            nb: 2,
            nk: 0,
        },
        ArxSettings {
            na: 2,
            nb: 0,
            nk: 1,
        },
    ] {
        let m = arx(&data, &s).unwrap();
        let ss = m.to_innovation_model().unwrap();
        assert_eq!(ss.nx(), 3 * s.max_lag());
        // The predictor of the realisation is a finite impulse response.
        let abar = &ss.a - &ss.k * &ss.c;
        let mut pow = abar.clone();
        for _ in 1..s.max_lag() {
            pow = &pow * &abar;
        }
        assert!(pow.amax() < 1e-12);
        let e = &data.experiments()[0];
        let t0 = s.max_lag();
        assert!(m.realisation_state(e, t0 - 1).is_none());
        let x0 = m.realisation_state(e, t0).unwrap();
        let rows = e.len() - t0;
        let (u, y) = (
            e.u.rows(t0, rows).into_owned(),
            e.y.rows(t0, rows).into_owned(),
        );
        for k in [1, 2, 5] {
            let direct = &m.predict(&data, k).unwrap()[0];
            let via_ss = ss.predict_k_step(&u, &y, &x0, k).unwrap();
            // Equal wherever both predict from measured data only.
            let first = m.first_predicted(k);
            assert_eq!(first, t0 + k - 1);
            assert!(direct.rows(0, first).iter().all(|v| v.is_nan()));
            let len = e.len() - first;
            let diff = (direct.rows(first, len) - via_ss.rows(k - 1, len)).amax();
            assert!(diff < 1e-9, "{s:?} k = {k}: {diff}");
        }
        // Fits: the realisation through the validation module (which
        // scores every sample from a least-squares initial state) agrees
        // to within the effect of the first samples.
        let f_arx = m.predict_fit(&data, 5).unwrap();
        let f_ss = predict_fit(&ss, &data, 5).unwrap();
        for (a, b) in f_arx.iter().zip(&f_ss) {
            assert!((a - b).abs() < 1.0, "{s:?}: {a} vs {b}");
        }
    }
}

#[test]
fn predict_fit_is_the_fit_over_the_predicted_samples() {
    let truth = synthetic::random_model(2, 1, 2, 3, 0.8);
    let a = synthetic::simulate(&truth, 300, 0.2, 1).unwrap();
    let b = synthetic::simulate(&truth, 200, 0.2, 2).unwrap();
    let data = IoData::merge(&[a, b]).unwrap();
    let m = arx(&data, &ArxSettings::lags(2)).unwrap();
    let skip = m.first_predicted(3);
    let p: Vec<_> = m
        .predict(&data, 3)
        .unwrap()
        .iter()
        .map(|p| p.rows(skip, p.nrows() - skip).into_owned())
        .collect();
    let y: Vec<_> = data
        .experiments()
        .iter()
        .map(|e| e.y.rows(skip, e.len() - skip).into_owned())
        .collect();
    assert_eq!(m.predict_fit(&data, 3).unwrap(), fit_percent(&y, &p));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let t = truth();
    let data = simulate_arx(&t, 100, 0.1, 3);
    // Too few samples for the lags: 2 * 20 + 2 * 20 = 80 parameters per output.
    let e = arx(&data, &ArxSettings::lags(20)).unwrap_err();
    assert!(
        matches!(e, SysidError::TooFewSamples { needed: 101, .. }),
        "{e}"
    );
    // No structure.
    let none = ArxSettings {
        na: 0,
        nb: 0,
        nk: 1,
    };
    assert!(matches!(
        arx(&data, &none),
        Err(SysidError::InvalidArgument(_))
    ));
    // A constant (zero) input.
    let e0 = &data.experiments()[0];
    let mut u = e0.u.clone();
    u.column_mut(1).fill(0.0);
    let flat = IoData::new(0.02, u, e0.y.clone()).unwrap();
    assert!(matches!(
        arx(&flat, &ArxSettings::lags(2)),
        Err(SysidError::ConstantInput { .. })
    ));
    // Two identical inputs: linearly dependent regressors.
    let mut u = e0.u.clone();
    let c0 = u.column(0).into_owned();
    u.column_mut(1).copy_from(&c0);
    let twin = IoData::new(0.02, u, e0.y.clone()).unwrap();
    assert!(matches!(
        arx(&twin, &ArxSettings::lags(2)),
        Err(SysidError::Numerical(_))
    ));
    // NaN never reaches the fit: the data set refuses it.
    let mut y = e0.y.clone();
    y[(5, 0)] = f64::NAN;
    assert!(matches!(
        IoData::new(0.02, e0.u.clone(), y),
        Err(SysidError::NonFinite { sample: 5, .. })
    ));
    // Horizon 0, and data of another shape.
    let m = arx(&data, &ArxSettings::lags(2)).unwrap();
    assert!(m.predict(&data, 0).is_err());
    let other = synthetic::simulate(&synthetic::random_model(2, 3, 2, 1, 0.5), 50, 0.1, 1).unwrap();
    assert!(matches!(
        m.predict(&other, 1),
        Err(SysidError::Dimension { .. })
    ));
    // Coefficients of the wrong shape.
    assert!(
        ArxModel::new(
            1.0,
            ArxSettings::lags(1),
            2,
            2,
            vec![DMatrix::zeros(2, 3)],
            vec![DMatrix::zeros(2, 2)]
        )
        .is_err()
    );
}

#[test]
fn baseline_reports_the_best_lag_count_per_horizon() {
    let truth = synthetic::random_model(4, 2, 2, 21, 0.95);
    let data = synthetic::simulate(&truth, 3000, 0.2, 5).unwrap();
    let (est, val) = data.split(0.5).unwrap();
    let b = arx_baseline(&est, &val, 2..=6, &[1, 5]).unwrap();
    assert_eq!(b.candidates.len(), 5);
    for (h, row) in b.rows.iter().enumerate() {
        let mean = |f: &[f64]| f.iter().sum::<f64>() / f.len() as f64;
        for c in &b.candidates {
            assert!(mean(&c.fits[h]) <= row.mean + 1e-12);
        }
        let m = arx(&est, &ArxSettings::lags(row.lags)).unwrap();
        assert_eq!(m.predict_fit(&val, row.horizon).unwrap(), row.fit);
    }
    // Too short for the long lags: those are skipped; for all of them, an error.
    let short = synthetic::simulate(&truth, 30, 0.2, 5).unwrap();
    let b = arx_baseline(&short, &val, 2..=10, &[1]).unwrap();
    assert!(!b.skipped.is_empty() && !b.candidates.is_empty());
    assert!(arx_baseline(&short, &val, 40..=41, &[1]).is_err());
    assert!(arx_baseline(&est, &val, 2..=3, &[0]).is_err());
}

#[test]
fn lags_beyond_the_operation_budget_are_refused_before_the_pass() {
    let truth = synthetic::random_model(2, 2, 2, 3, 0.8);
    let data = synthetic::simulate(&truth, 20_000, 0.05, 1).unwrap();
    // 1000 lags: 4000 parameters per output on 19,000 rows, 3e11 operations.
    let e = arx(&data, &ArxSettings::lags(1000)).unwrap_err();
    assert!(
        matches!(
            e,
            SysidError::TooLarge {
                method: SizedMethod::Arx,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("4000 parameters per output"), "{e}");
    // 10 lags on the same data: 2e7 operations.
    assert!(arx(&data, &ArxSettings::lags(10)).is_ok());
}

#[test]
fn default_lags_keeps_what_fits_and_shrinks_a_short_record() {
    // 2 inputs, 2 outputs: ARX(l) has 4 l parameters per output and
    // 200 - l rows on 200 samples, 180 - 2 l on experiments of 100 + 80.
    let m = synthetic::random_model(2, 2, 2, 5, 0.8);
    let one = synthetic::simulate(&m, 200, 0.1, 1).unwrap();
    assert_eq!(ArxSettings::lags(7).regression_rows(&one), 193);
    // 30 lags: 170 rows > 120 parameters, kept.
    assert_eq!(default_lags(&one, 30, 1, ArxSettings::lags), 30);
    // 40 lags: 160 rows for 160 parameters, too few; 22 is the largest
    // with twice as many (178 >= 176; 23: 177 < 184).
    assert!(!ArxSettings::lags(40).has_rows_on(&one));
    assert!(ArxSettings::lags(39).has_rows_on(&one));
    assert_eq!(default_lags(&one, 40, 1, ArxSettings::lags), 22);
    // None in 30..40: the preferred count, whose fit then fails.
    assert_eq!(default_lags(&one, 40, 30, ArxSettings::lags), 40);
    let two = IoData::merge(&[
        synthetic::simulate(&m, 100, 0.1, 2).unwrap(),
        synthetic::simulate(&m, 80, 0.1, 3).unwrap(),
    ])
    .unwrap();
    assert_eq!(ArxSettings::lags(7).regression_rows(&two), 166);
    // 180 - 2 l >= 8 l up to l = 18.
    assert_eq!(default_lags(&two, 40, 1, ArxSettings::lags), 18);
}
