//! Stage 2: gyro bias and noise covariance from experiment 4 (motors off),
//! the linearisation point `U0` from experiment 1 (hover).

use super::config::Config;
use super::error::{Context, PipelineError, Result};
use super::experiments::Experiments;
use kestrel_kalman::noise::{NoiseSettings, estimate_sensor_statistics};
use kestrel_tricopter_model::PlantConfig;
use nalgebra::DMatrix;

/// The thesis's trim (7.2): `pwm1..3 - throttle` and the servo (us).
pub const THESIS_TRIM: [f64; 4] = [15.63, 0.85, -16.01, 1467.7];

/// Stage 2's result.
#[derive(Clone, Debug)]
pub struct SensorStats {
    /// Gyro bias (rad/s).
    pub bias: [f64; 3],
    /// Gyro noise covariance (a floor of `1e-12` on the diagonal keeps a
    /// quantised, silent channel from making it singular).
    pub covariance: DMatrix<f64>,
    /// Ground samples used.
    pub samples: usize,
    /// Standard errors of the bias (rad/s).
    pub bias_standard_error: Vec<f64>,
    /// Lag-1 autocorrelation per axis (white noise stays within about
    /// `2 / sqrt(samples)`).
    pub lag1_autocorrelation: Vec<f64>,
    /// The simulator's gyro bias and covariance, when the flights are simulated.
    pub truth: Option<SensorTruth>,
    /// Estimated linearisation point `[pwm1 - throttle, pwm2 - throttle,
    /// pwm3 - throttle, servo]` (us).
    pub u0: [f64; 4],
    /// The simulator's trim offsets, when known.
    pub true_u0: Option<[f64; 4]>,
}

/// The simulator's gyro parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorTruth {
    /// Bias (rad/s).
    pub bias: [f64; 3],
    /// Noise covariance.
    pub covariance: [[f64; 3]; 3],
}

/// Stage 2.
///
/// # Errors
/// Too few samples after `sensor.ground_skip` / `sensor.hover_trim`;
/// kestrel-kalman's statistics errors.
pub fn run(cfg: &Config, ex: &Experiments) -> Result<SensorStats> {
    let ground = ex.flight(4, "the ground experiment")?;
    let rows: Vec<[f64; 3]> = ground
        .t
        .iter()
        .zip(&ground.gyro)
        .filter(|(t, _)| **t >= cfg.sensor.ground_skip)
        .map(|(_, g)| *g)
        .collect();
    if rows.len() < 10 {
        return Err(PipelineError::Data(format!(
            "experiment 4 (ground): fewer than 10 samples after sensor.ground_skip = {} s",
            cfg.sensor.ground_skip
        )));
    }
    // kestrel-kalman's sensor statistics (true rate zero on the ground).
    let stats = estimate_sensor_statistics(&rows, &NoiseSettings::default())
        .ctx(|| "gyro statistics of experiment 4".into())?;
    let bias: [f64; 3] = std::array::from_fn(|j| stats.bias[j]);
    let covariance = stats.covariance_with_floor(1e-12);
    let truth = ground.true_offsets.map(|_| {
        let g = PlantConfig::default().gyro;
        SensorTruth {
            bias: g.bias,
            covariance: g.covariance,
        }
    });
    // Trim (7.2): hover flight, airborne, ends cut.
    let hover = ex.flight(1, "the hover experiment")?;
    let t_end = hover.t.last().copied().unwrap_or(0.0);
    let idx: Vec<usize> = (0..hover.t.len())
        .filter(|&k| {
            hover.airborne[k]
                && hover.t[k] >= cfg.sensor.hover_trim
                && hover.t[k] <= t_end - cfg.sensor.hover_trim
        })
        .collect();
    if idx.len() < 10 {
        return Err(PipelineError::Data(
            "experiment 1 (hover): fewer than 10 airborne samples after sensor.hover_trim".into(),
        ));
    }
    let m = idx.len() as f64;
    let u0: [f64; 4] = std::array::from_fn(|j| {
        idx.iter()
            .map(|&k| {
                if j < 3 {
                    hover.pwm[k][j] - hover.throttle[k]
                } else {
                    hover.pwm[k][3]
                }
            })
            .sum::<f64>()
            / m
    });
    Ok(SensorStats {
        bias,
        covariance,
        samples: stats.samples,
        bias_standard_error: stats.bias_standard_error.as_slice().to_vec(),
        lag1_autocorrelation: stats.lag1_autocorrelation.as_slice().to_vec(),
        truth,
        u0,
        true_u0: hover.true_offsets,
    })
}
