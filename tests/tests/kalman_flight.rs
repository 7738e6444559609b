//! The stationary Kalman filter of kestrel-kalman on a simulated flight of
//! kestrel-tricopter-model (experiment no. 3, coupled excitation): the
//! estimated body rates p, q, r against the raw gyro and a first-order
//! low-pass filter of equal delay, as a table (run with `--nocapture`).
//!
//! The filter is designed on the simulator's reduced rate model with
//! actuators (8 states, 4 PWM inputs, 3 gyro outputs, 50 Hz, linearised at
//! hover), the thesis's gyro covariance (7.6) and bias (7.5), and a
//! hand-chosen process noise (not fitted to the true rates).

use kestrel_kalman::{KalmanDesign, NoiseModel};
use kestrel_tricopter_model::{
    Experiment, Params, RateInputs, RateModelKind, SimSettings, THESIS_GYRO_BIAS,
    THESIS_GYRO_COVARIANCE, rate_model_discrete, simulate,
};
use nalgebra::{DMatrix, DVector};

/// RMS of `est[k] - truth[k - lag]` (fractional lag by linear interpolation) over `range`.
fn rms_lagged(est: &[f64], truth: &[f64], lag: f64, range: std::ops::Range<usize>) -> f64 {
    let (i, f) = (lag.floor() as usize, lag - lag.floor());
    let mut s = 0.0;
    for k in range.clone() {
        let t = (1.0 - f) * truth[k - i] + f * truth[k - i - 1];
        s += (est[k] - t).powi(2);
    }
    (s / range.len() as f64).sqrt()
}

/// The lag (samples, 0.05 steps up to 10) at which an estimate best matches the truth.
fn delay(est: &[f64], truth: &[f64], range: std::ops::Range<usize>) -> f64 {
    (0..=200)
        .map(|i| i as f64 * 0.05)
        .min_by(|a, b| {
            rms_lagged(est, truth, *a, range.clone()).total_cmp(&rms_lagged(
                est,
                truth,
                *b,
                range.clone(),
            ))
        })
        .unwrap()
}

/// First-order low-pass `y_k = y_{k-1} + alpha (x_k - y_{k-1})` (DC delay `(1 - alpha)/alpha` samples).
fn low_pass(x: &[f64], alpha: f64, start: usize) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    let mut s = x[start];
    for k in start..x.len() {
        s += alpha * (x[k] - s);
        y[k] = s;
    }
    y
}

/// RMS errors of one axis: raw gyro, gyro - bias, equal-delay low-pass, Kalman.
struct Row {
    raw: f64,
    unbiased: f64,
    low_pass: f64,
    kalman: f64,
}

/// Flies experiment no. 3 with the gyro covariance scaled by `noise_scale`,
/// filters it, prints the table and returns the errors per axis.
fn flight_table(noise_scale: f64) -> Vec<Row> {
    let model = rate_model_discrete(
        &Params::default(),
        RateModelKind::WithActuators,
        RateInputs::Pwm,
        0.02,
    )
    .unwrap();
    assert_eq!((model.nx(), model.nu(), model.ny()), (8, 4, 3));
    let mut settings = SimSettings::new(Experiment::Coupled, 60.0, 1);
    for row in settings.plant.gyro.covariance.iter_mut() {
        for v in row.iter_mut() {
            *v *= noise_scale;
        }
    }
    let log = simulate(&settings).unwrap();

    // Process noise: the hover-linearised rate model is far from exact at
    // 1 rad/s excitation with a varying throttle, so the rate states get a
    // large process noise (std 0.03 rad/s per step) besides the rotor
    // speeds and the servo. Hand-chosen, not fitted to the true rates.
    // (With the gust-only value, 2.5e-5, the filter trusts the model too
    // much and loses to the raw gyro: the model error dominates.)
    let q = DMatrix::from_diagonal(&DVector::from_vec(vec![
        1e-3, 1e-3, 1e-3, 1.0, 1.0, 1.0, 1e-6, 1e-4,
    ]));
    let r = DMatrix::from_fn(3, 3, |i, j| THESIS_GYRO_COVARIANCE[i][j] * noise_scale);
    let noise = NoiseModel {
        g: None,
        q,
        r,
        cross: None,
        bias: Some(DVector::from_column_slice(&THESIS_GYRO_BIAS)),
    };
    let design = KalmanDesign::new(&model, &noise).unwrap();
    let mut filter = design.filter::<f64, 8, 4, 3>().unwrap();
    println!(
        "\ngyro covariance = {noise_scale} x (7.6); stationary filter: 8 states, 4 inputs, 3 outputs, {} multiply-adds per sample",
        filter.gains().multiply_adds()
    );

    // Run from take-off (the linear model is meaningless on the ground).
    let first = log.rows.iter().position(|r| r.airborne).unwrap();
    let n = log.rows.len();
    let mut est = vec![[0.0; 3]; n];
    for (k, row) in log.rows.iter().enumerate().skip(first) {
        filter.update(&row.gyro).unwrap();
        est[k] = filter.output_estimate();
        filter.predict(&row.pwm).unwrap();
    }
    assert_eq!(filter.status().rejected, 0);

    // Evaluate during the excitation (10 s to 55 s), all of it airborne.
    let range = 500..2750;
    assert!(log.rows[range.clone()].iter().all(|r| r.airborne));
    let names = ["p", "q", "r"];
    println!(
        "| axis | RMS error (rad/s): raw gyro | gyro - bias | low-pass of gyro - bias, equal delay (alpha, delay) | Kalman (delay) | best low-pass (alpha, delay) |"
    );
    println!("|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    for (axis, name) in names.iter().enumerate() {
        let truth: Vec<f64> = log.rows.iter().map(|r| r.state[9 + axis]).collect();
        let raw: Vec<f64> = log.rows.iter().map(|r| r.gyro[axis]).collect();
        let unbiased: Vec<f64> = raw.iter().map(|v| v - THESIS_GYRO_BIAS[axis]).collect();
        let kal: Vec<f64> = est.iter().map(|e| e[axis]).collect();
        let rms = |x: &[f64]| rms_lagged(x, &truth, 0.0, range.clone());
        let d_kal = delay(&kal, &truth, range.clone());
        let alpha_eq = 1.0 / (1.0 + d_kal);
        let lp_eq = low_pass(&unbiased, alpha_eq, first);
        let (mut best_alpha, mut best_rms) = (1.0, f64::INFINITY);
        for i in 1..=100 {
            let alpha = i as f64 / 100.0;
            let e = rms(&low_pass(&unbiased, alpha, first));
            if e < best_rms {
                (best_alpha, best_rms) = (alpha, e);
            }
        }
        let row = Row {
            raw: rms(&raw),
            unbiased: rms(&unbiased),
            low_pass: rms(&lp_eq),
            kalman: rms(&kal),
        };
        println!(
            "| {name} | {:.5} | {:.5} | {:.5} ({alpha_eq:.2}, {:.2} samples) | {:.5} ({d_kal:.2} samples) | {best_rms:.5} ({best_alpha:.2}, {:.2} samples) |",
            row.raw,
            row.unbiased,
            row.low_pass,
            (1.0 - alpha_eq) / alpha_eq,
            row.kalman,
            (1.0 - best_alpha) / best_alpha,
        );
        rows.push(row);
    }
    rows
}

#[test]
fn stationary_filter_on_flight_three() {
    // With the thesis's very quiet gyro (std 1.1e-3 to 3.6e-3 rad/s) the
    // filter mainly removes the bias; against the bias-corrected gyro and
    // the equal-delay low-pass it is level (the linear model's error at
    // 1 rad/s excitation is as large as the gyro noise).
    for (axis, row) in flight_table(1.0).iter().enumerate() {
        assert!(
            row.kalman < row.raw,
            "axis {axis}: {} vs {}",
            row.kalman,
            row.raw
        );
        assert!(
            row.kalman <= 1.01 * row.unbiased,
            "axis {axis}: {} vs {}",
            row.kalman,
            row.unbiased
        );
        assert!(
            row.kalman <= 1.01 * row.low_pass,
            "axis {axis}: {} vs {}",
            row.kalman,
            row.low_pass
        );
    }
}
