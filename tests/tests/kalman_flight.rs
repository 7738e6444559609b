//! The stationary Kalman filter of kestrel-kalman on simulated flights of
//! kestrel-tricopter-model: the estimated body rates p, q, r against the
//! true rates, compared with the raw gyro, the gyro minus its estimated
//! bias, and a first-order low-pass of the latter with the same delay as
//! the filter. The table is printed (run with `--nocapture`) and every
//! figure in it is computed here.
//!
//! Nothing is tuned on the true rates:
//! - **R and the bias** come from a separate 20 s ground log (motors off)
//!   through `kestrel_kalman::noise::estimate_sensor_statistics` (thesis
//!   7.1-7.2); the sample covariance includes the gyro's quantisation.
//! - **The model** is the simulator's linearised rate model with actuator
//!   states (`[p, q, r, w1, w2, w3, alpha, alpha_dot]`, 4 PWM inputs, ZOH at
//!   50 Hz), augmented with three gust-torque states: the plant's gusts are
//!   a first-order Gauss-Markov torque (`GustConfig`: std `sigma`, time
//!   constant `tau`), held over each sample, so `d_{k+1} = phi d_k + w_k`
//!   with `phi = exp(-Ts/tau)` and the torque enters the rates through the
//!   ZOH-discretised `1/I` column. 11 states in all.
//! - **Q**: the gust driving noise `sigma^2 (1 - phi^2)` from the gust
//!   model, plus a model-error variance `q_rate` on the rate states that
//!   covers the linearisation error (throttle changes, gyroscopic
//!   coupling). `q_rate` is chosen from a grid by innovation consistency on
//!   a *different* training flight (seed 2) of the same experiment: the
//!   mean normalised innovation `e' S^-1 e / ny` closest to 1. The table's
//!   flight (seed 1) is not used for the design.
//!
//! Why the earlier design only tied: it used the 8-state model without the
//! gust states and a hand-chosen, large rate process noise (std 0.03 rad/s
//! per step), so its gain was close to 1 and its estimate was essentially
//! the bias-corrected gyro. The gust torque is a slowly varying, strongly
//! correlated disturbance; with it as states the model predicts the rates
//! to within a fraction of the gyro noise and the filter can average.

use kestrel_core::c2d;
use kestrel_core::formats::SsModel;
use kestrel_kalman::noise::{NoiseSettings, SensorStatistics, estimate_sensor_statistics};
use kestrel_kalman::{KalmanDesign, NoiseModel};
use kestrel_tricopter_model::{
    Experiment, FlightLog, GustConfig, Params, RateInputs, RateModelKind, SimSettings, rate_model,
    simulate,
};
use nalgebra::{DMatrix, DVector};

const TS: f64 = 0.02;
const NX: usize = 11;
/// Evaluation window: 10 s to 55 s of a 60 s flight (airborne, excitation on).
const WINDOW: std::ops::Range<usize> = 500..2750;

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

/// The lag (samples, steps of 0.05 up to 10) at which an estimate best matches the truth.
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

/// First-order low-pass `y_k = y_{k-1} + alpha (x_k - y_{k-1})`; its delay
/// at low frequency is `(1 - alpha) / alpha` samples.
fn low_pass(x: &[f64], alpha: f64, start: usize) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    let mut s = x[start];
    for k in start..x.len() {
        s += alpha * (x[k] - s);
        y[k] = s;
    }
    y
}

/// The 8-state rate model with actuators, plus three gust-torque states.
fn design_model(params: &Params, gust: &GustConfig) -> SsModel {
    let cont = rate_model(params, RateModelKind::WithActuators, RateInputs::Pwm).unwrap();
    let n = cont.nx();
    assert_eq!(n + 3, NX);
    // Torque inputs: d(p, q, r)/dt += torque / I.
    let mut b = DMatrix::zeros(n, 7);
    b.columns_mut(0, 4).copy_from(&cont.b);
    for (i, inertia) in [params.ixx, params.iyy, params.izz].iter().enumerate() {
        b[(i, 4 + i)] = 1.0 / inertia;
    }
    let d = c2d(&cont.a, &b, TS).unwrap();
    let phi = (-TS / gust.tau).exp();
    let mut a = DMatrix::zeros(NX, NX);
    a.view_mut((0, 0), (n, n)).copy_from(&d.a);
    a.view_mut((0, n), (n, 3)).copy_from(&d.b.columns(4, 3));
    for i in 0..3 {
        a[(n + i, n + i)] = phi;
    }
    let mut bb = DMatrix::zeros(NX, 4);
    bb.view_mut((0, 0), (n, 4)).copy_from(&d.b.columns(0, 4));
    let c = DMatrix::from_fn(3, NX, |i, j| if i == j { 1.0 } else { 0.0 });
    let mut m = SsModel::new(TS, a, bb, c, DMatrix::zeros(3, 4)).unwrap();
    m.u0 = cont.u0.clone();
    m.y0 = cont.y0.clone();
    m
}

/// Q: gust driving noise from the gust model, `q_rate` on the rate states,
/// and a negligible 1e-12 on the actuator states (they are driven by the
/// known inputs only).
fn design(
    model: &SsModel,
    gust: &GustConfig,
    stats: &SensorStatistics,
    q_rate: f64,
) -> KalmanDesign {
    let phi = (-TS / gust.tau).exp();
    let mut q = DMatrix::zeros(NX, NX);
    for i in 0..3 {
        q[(i, i)] = q_rate;
        q[(8 + i, 8 + i)] = gust.torque_std[i].powi(2) * (1.0 - phi * phi);
    }
    for i in 3..8 {
        q[(i, i)] = 1e-12;
    }
    let noise = NoiseModel {
        g: None,
        q,
        r: stats.covariance_with_floor(1e-10),
        cross: None,
        bias: Some(stats.bias.clone()),
    };
    KalmanDesign::new(model, &noise).unwrap()
}

/// Filter estimates of p, q, r per sample (zero before take-off) and the
/// mean normalised innovation squared over the window.
fn run(design: &KalmanDesign, log: &FlightLog) -> (Vec<[f64; 3]>, f64) {
    let mut filter = design.filter::<f64, NX, 4, 3>().unwrap();
    let s_inv = design
        .filter
        .innovation_covariance
        .clone()
        .try_inverse()
        .unwrap();
    let first = log.rows.iter().position(|r| r.airborne).unwrap();
    let mut est = vec![[0.0; 3]; log.rows.len()];
    let mut nis = 0.0;
    for (k, row) in log.rows.iter().enumerate().skip(first) {
        filter.update(&row.gyro).unwrap();
        est[k] = filter.output_estimate();
        if WINDOW.contains(&k) {
            let e = DVector::from_column_slice(filter.innovation());
            nis += (e.transpose() * &s_inv * &e)[(0, 0)] / 3.0;
        }
        filter.predict(&row.pwm).unwrap();
    }
    assert_eq!(filter.status().rejected, 0);
    (est, nis / WINDOW.len() as f64)
}

/// RMS errors (rad/s) of one axis against the true rate.
struct Row {
    signal: f64,
    raw: f64,
    unbiased: f64,
    low_pass: f64,
    alpha: f64,
    kalman: f64,
    kalman_delay: f64,
}

/// Designs the filter for `experiment` (q_rate by innovation consistency on
/// the training flight), runs it on the test flight and prints the table.
fn flight_table(experiment: Experiment, stats: &SensorStatistics) -> Vec<Row> {
    let params = Params::default();
    let test = simulate(&SimSettings::new(experiment, 60.0, 1)).unwrap();
    let training = simulate(&SimSettings::new(experiment, 60.0, 2)).unwrap();
    let gust = test.settings.plant.gust;
    let model = design_model(&params, &gust);
    let candidates = [0.0, 1e-6, 1e-5, 1e-4, 1e-3];
    let (q_rate, nis) = candidates
        .iter()
        .map(|&q| (q, run(&design(&model, &gust, stats, q), &training).1))
        .min_by(|a, b| (a.1 - 1.0).abs().total_cmp(&(b.1 - 1.0).abs()))
        .unwrap();
    let design = design(&model, &gust, stats, q_rate);
    let (est, _) = run(&design, &test);
    let gains = design.gains::<f64, NX, 4, 3>().unwrap();

    assert!(test.rows[WINDOW].iter().all(|r| r.airborne));
    let first = test.rows.iter().position(|r| r.airborne).unwrap();
    println!(
        "\n{experiment:?} flight (seed 1), 10-55 s; filter: {NX} states, 4 inputs, 3 outputs, {} multiply-adds per sample; \
         q_rate = {q_rate:e} (training-flight NIS/ny = {nis:.2}); bias and R from a ground log",
        gains.multiply_adds()
    );
    println!(
        "| axis | true rate RMS | raw gyro | gyro - bias | low-pass, equal delay (alpha) | Kalman (delay, samples) |"
    );
    println!("|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    for (axis, name) in ["p", "q", "r"].iter().enumerate() {
        let truth: Vec<f64> = test.rows.iter().map(|r| r.state[9 + axis]).collect();
        let raw: Vec<f64> = test.rows.iter().map(|r| r.gyro[axis]).collect();
        let unbiased: Vec<f64> = raw.iter().map(|v| v - stats.bias[axis]).collect();
        let kal: Vec<f64> = est.iter().map(|e| e[axis]).collect();
        let rms = |x: &[f64]| rms_lagged(x, &truth, 0.0, WINDOW);
        let kalman_delay = delay(&kal, &truth, WINDOW);
        let alpha = 1.0 / (1.0 + kalman_delay);
        let row = Row {
            signal: rms(&vec![0.0; truth.len()]),
            raw: rms(&raw),
            unbiased: rms(&unbiased),
            low_pass: rms(&low_pass(&unbiased, alpha, first)),
            alpha,
            kalman: rms(&kal),
            kalman_delay,
        };
        println!(
            "| {name} | {:.4} | {:.5} | {:.5} | {:.5} ({:.2}) | {:.5} ({:.2}) |",
            row.signal,
            row.raw,
            row.unbiased,
            row.low_pass,
            row.alpha,
            row.kalman,
            row.kalman_delay
        );
        rows.push(row);
    }
    rows
}

fn ground_statistics() -> SensorStatistics {
    let ground = simulate(&SimSettings::new(Experiment::Ground, 20.0, 7)).unwrap();
    assert!(ground.rows.iter().all(|r| !r.airborne));
    let gyro: Vec<[f64; 3]> = ground.rows.iter().map(|r| r.gyro).collect();
    let stats = estimate_sensor_statistics(&gyro, &NoiseSettings::default()).unwrap();
    // The estimated bias is within 5 standard errors of the simulator's (7.5).
    let truth = test_gyro_bias();
    for (i, b) in truth.iter().enumerate() {
        assert!((stats.bias[i] - b).abs() < 5.0 * stats.bias_standard_error[i]);
    }
    stats
}

fn test_gyro_bias() -> [f64; 3] {
    SimSettings::new(Experiment::Ground, 1.0, 0).plant.gyro.bias
}

fn assert_wins(rows: &[Row]) {
    for (axis, row) in rows.iter().enumerate() {
        for (what, other) in [
            ("raw gyro", row.raw),
            ("gyro - bias", row.unbiased),
            ("equal-delay low-pass", row.low_pass),
        ] {
            assert!(
                row.kalman < other,
                "axis {axis}: Kalman {} vs {what} {other}",
                row.kalman
            );
        }
    }
}

#[test]
fn stationary_filter_beats_gyro_and_low_pass_in_hover() {
    let stats = ground_statistics();
    let rows = flight_table(Experiment::Hover, &stats);
    assert_wins(&rows);
}

#[test]
fn stationary_filter_beats_gyro_and_low_pass_in_coupled_excitation() {
    let stats = ground_statistics();
    let rows = flight_table(Experiment::Coupled, &stats);
    assert_wins(&rows);
}
