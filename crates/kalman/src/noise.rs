//! Sensor statistics from a stationary segment (thesis 7.1-7.2): the bias
//! vector and the measurement-noise covariance `R` of a gyro (or any
//! sensor) from samples taken while the true signal is known (on the
//! ground: zero rate) or constant on average (hover).
//!
//! ```
//! use kestrel_kalman::noise::{estimate_sensor_statistics, NoiseSettings};
//! // Three gyro channels on the ground (true rate zero), one row per sample.
//! let samples = [[0.011, -0.002, 0.003], [0.009, 0.001, 0.004], [0.010, -0.001, 0.002]];
//! let stats = estimate_sensor_statistics(&samples, &NoiseSettings::default())?;
//! assert!((stats.bias[0] - 0.010).abs() < 1e-12);   // the mean minus the true value (0)
//! assert!((stats.covariance[(0, 0)] - 1e-6).abs() < 1e-15); // unbiased sample covariance
//! // The filter's R: the covariance, with a floor for a quantised, silent channel.
//! let r = stats.covariance_with_floor(1e-8);
//! assert_eq!(r.shape(), (3, 3));
//! # Ok::<(), kestrel_kalman::KalmanError>(())
//! ```

use nalgebra::{DMatrix, DVector};

use crate::KalmanError;

/// How the segment's slow part is removed before the noise covariance is estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Detrend {
    /// Remove the mean only: the sensor's bias is constant over the segment.
    #[default]
    Mean,
    /// Remove a straight line per channel (least squares in the sample
    /// index): a bias that drifts slowly (temperature) does not inflate `R`.
    /// The bias is then the line's value at the middle of the segment.
    Linear,
}

/// Settings of [`estimate_sensor_statistics`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NoiseSettings {
    /// The true value of the measured signal over the segment, one entry
    /// per channel (`None`: zero, a gyro at rest). The bias is the
    /// estimated mean minus this.
    pub reference: Option<Vec<f64>>,
    /// How the slow part is removed before the covariance is estimated.
    pub detrend: Detrend,
}

/// Bias and noise statistics of a sensor estimated from a stationary segment.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorStatistics {
    /// Number of samples used.
    pub samples: usize,
    /// Sample mean per channel.
    pub mean: DVector<f64>,
    /// Bias per channel: the mean (for [`Detrend::Linear`] the fitted line
    /// at the middle of the segment, which is the same) minus the reference.
    /// This is what [`NoiseModel::bias`](crate::NoiseModel::bias) takes.
    pub bias: DVector<f64>,
    /// Standard error of each bias entry, `sigma / sqrt(samples)`, valid
    /// for white noise (compare with `lag1_autocorrelation`).
    pub bias_standard_error: DVector<f64>,
    /// Drift per sample of each channel (the fitted slope); zero for [`Detrend::Mean`].
    pub drift_per_sample: DVector<f64>,
    /// The unbiased sample covariance of the detrended samples (divided by
    /// `samples - 1`, or `samples - 2` after a linear detrend): the
    /// measurement-noise covariance `R` of the filter.
    pub covariance: DMatrix<f64>,
    /// Standard deviation per channel (square root of the covariance's diagonal).
    pub std_dev: DVector<f64>,
    /// Lag-one autocorrelation of each detrended channel: near zero
    /// (within about `2 / sqrt(samples)`) for white noise; a large value
    /// says the segment is not stationary or the noise is coloured, and `R`
    /// from it should not be trusted as white measurement noise. Zero for a
    /// channel without variance.
    pub lag1_autocorrelation: DVector<f64>,
}

impl SensorStatistics {
    /// The covariance with each diagonal entry raised to at least
    /// `min_variance` (a quantised sensor can read a constant on the
    /// ground, which would give a singular `R`). Off-diagonal entries are kept.
    pub fn covariance_with_floor(&self, min_variance: f64) -> DMatrix<f64> {
        let mut r = self.covariance.clone();
        for i in 0..r.nrows() {
            if r[(i, i)] < min_variance {
                r[(i, i)] = min_variance;
            }
        }
        r
    }
}

/// Estimates the bias and the noise covariance of a sensor from a
/// stationary segment, `samples[k][i]` = channel `i` at sample `k`.
///
/// Errors: fewer than 2 samples (3 for [`Detrend::Linear`]) or no channel
/// ([`KalmanError::InvalidArgument`]), rows of different length or a
/// reference of the wrong length ([`KalmanError::DimensionMismatch`]),
/// NaN or infinite samples or reference ([`KalmanError::NonFinite`], naming
/// the sample and the channel).
pub fn estimate_sensor_statistics<R: AsRef<[f64]>>(
    samples: &[R],
    settings: &NoiseSettings,
) -> Result<SensorStatistics, KalmanError> {
    let n = samples.len();
    let min_samples = match settings.detrend {
        Detrend::Mean => 2,
        Detrend::Linear => 3,
    };
    if n < min_samples {
        return Err(KalmanError::InvalidArgument {
            name: "samples",
            reason: format!(
                "{n} samples, at least {min_samples} are needed for {:?} detrending",
                settings.detrend
            ),
        });
    }
    let m = samples[0].as_ref().len();
    if m == 0 {
        return Err(KalmanError::InvalidArgument {
            name: "samples",
            reason: "the samples have no channel".into(),
        });
    }
    for (k, row) in samples.iter().enumerate() {
        let row = row.as_ref();
        if row.len() != m {
            return Err(KalmanError::DimensionMismatch {
                name: "samples",
                expected_rows: 1,
                expected_cols: m,
                found_rows: 1,
                found_cols: row.len(),
            });
        }
        if let Some(i) = row.iter().position(|v| !v.is_finite()) {
            return Err(KalmanError::NonFinite {
                name: "samples",
                row: k,
                col: i,
            });
        }
    }
    let reference = match &settings.reference {
        None => DVector::zeros(m),
        Some(r) => {
            if r.len() != m {
                return Err(KalmanError::DimensionMismatch {
                    name: "reference",
                    expected_rows: m,
                    expected_cols: 1,
                    found_rows: r.len(),
                    found_cols: 1,
                });
            }
            if let Some(i) = r.iter().position(|v| !v.is_finite()) {
                return Err(KalmanError::NonFinite {
                    name: "reference",
                    row: i,
                    col: 0,
                });
            }
            DVector::from_column_slice(r)
        }
    };

    // Two passes (mean first, then centred sums): no cancellation for a
    // small noise on a large bias.
    let nf = n as f64;
    let mut mean = DVector::<f64>::zeros(m);
    for row in samples {
        for (acc, v) in mean.iter_mut().zip(row.as_ref()) {
            *acc += v;
        }
    }
    mean /= nf;

    // Slope in the centred sample index t_k = k - (n-1)/2 (sum t_k = 0, so
    // the intercept at the middle is the mean).
    let mid = (nf - 1.0) / 2.0;
    let mut drift = DVector::<f64>::zeros(m);
    if settings.detrend == Detrend::Linear {
        // sum t_k^2 = n (n^2 - 1) / 12
        let stt = nf * (nf * nf - 1.0) / 12.0;
        for (k, row) in samples.iter().enumerate() {
            let t = k as f64 - mid;
            for (i, v) in row.as_ref().iter().enumerate() {
                drift[i] += t * (v - mean[i]);
            }
        }
        drift /= stt;
    }

    let residual = |k: usize, i: usize, v: f64| v - mean[i] - drift[i] * (k as f64 - mid);
    let mut cov = DMatrix::<f64>::zeros(m, m);
    let mut lag1 = DVector::<f64>::zeros(m);
    let mut previous = DVector::<f64>::zeros(m);
    let mut e = DVector::<f64>::zeros(m);
    for (k, row) in samples.iter().enumerate() {
        for (i, v) in row.as_ref().iter().enumerate() {
            e[i] = residual(k, i, *v);
        }
        for c in 0..m {
            for r in c..m {
                cov[(r, c)] += e[r] * e[c];
            }
        }
        if k > 0 {
            for i in 0..m {
                lag1[i] += e[i] * previous[i];
            }
        }
        previous.copy_from(&e);
    }
    let sum_sq = cov.diagonal();
    let dof = nf
        - if settings.detrend == Detrend::Linear {
            2.0
        } else {
            1.0
        };
    for c in 0..m {
        for r in c..m {
            cov[(r, c)] /= dof;
            cov[(c, r)] = cov[(r, c)];
        }
    }
    for i in 0..m {
        lag1[i] = if sum_sq[i] > 0.0 {
            lag1[i] / sum_sq[i]
        } else {
            0.0
        };
    }
    let std_dev = cov.diagonal().map(f64::sqrt);
    let bias_standard_error = &std_dev / nf.sqrt();
    let bias = &mean - &reference;
    Ok(SensorStatistics {
        samples: n,
        mean,
        bias,
        bias_standard_error,
        drift_per_sample: drift,
        covariance: cov,
        std_dev,
        lag1_autocorrelation: lag1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::Rng;

    /// Samples `bias + L w_k (+ drift k)` with white unit normal `w_k`.
    fn generate(
        rng: &mut Rng,
        n: usize,
        bias: &[f64],
        l: &DMatrix<f64>,
        drift: &[f64],
    ) -> Vec<Vec<f64>> {
        let m = bias.len();
        (0..n)
            .map(|k| {
                let w = DVector::from_fn(m, |_, _| rng.normal());
                let v = l * w;
                (0..m)
                    .map(|i| bias[i] + v[i] + drift[i] * k as f64)
                    .collect()
            })
            .collect()
    }

    fn rel_frobenius(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).norm() / b.norm()
    }

    #[test]
    fn recovers_known_bias_and_correlated_covariance() {
        let mut rng = Rng::new(7);
        // A gyro-like noise: sigma about 0.01 rad/s, correlated channels.
        let l = DMatrix::from_row_slice(
            3,
            3,
            &[0.010, 0.0, 0.0, 0.004, 0.008, 0.0, -0.002, 0.003, 0.012],
        );
        let r_true = &l * l.transpose();
        let bias = [-9.7e-4, 4.9e-3, 0.021];
        let n = 40_000;
        let samples = generate(&mut rng, n, &bias, &l, &[0.0; 3]);
        let s = estimate_sensor_statistics(&samples, &NoiseSettings::default()).unwrap();
        assert_eq!(s.samples, n);
        for i in 0..3 {
            // The bias within 4 standard errors, and the standard error right.
            let se = r_true[(i, i)].sqrt() / (n as f64).sqrt();
            assert!((s.bias[i] - bias[i]).abs() < 4.0 * se, "channel {i}");
            assert!((s.bias_standard_error[i] / se - 1.0).abs() < 0.05);
            // White noise: |rho_1| < 4 / sqrt(n).
            assert!(s.lag1_autocorrelation[i].abs() < 4.0 / (n as f64).sqrt());
            assert_eq!(s.drift_per_sample[i], 0.0);
        }
        // Sample covariance: relative error ~ sqrt(2 / n) = 0.7 %.
        assert!(rel_frobenius(&s.covariance, &r_true) < 0.03);
        assert_eq!(s.covariance, s.covariance.transpose());
        assert!(s.covariance.clone().cholesky().is_some());
    }

    #[test]
    fn small_case_matches_closed_form() {
        // Two channels, three samples: mean and unbiased covariance by hand.
        let samples = [[1.0, 2.0], [3.0, 2.0], [5.0, 5.0]];
        let s = estimate_sensor_statistics(
            &samples,
            &NoiseSettings {
                reference: Some(vec![1.0, -1.0]),
                ..Default::default()
            },
        )
        .unwrap();
        assert!((s.mean[0] - 3.0).abs() < 1e-15 && (s.mean[1] - 3.0).abs() < 1e-15);
        assert!((s.bias[0] - 2.0).abs() < 1e-15 && (s.bias[1] - 4.0).abs() < 1e-15);
        // deviations (-2, 0, 2) and (-1, -1, 2): var 8/2, 6/2, cov 6/2.
        let expected = DMatrix::from_row_slice(2, 2, &[4.0, 3.0, 3.0, 3.0]);
        assert!(rel_frobenius(&s.covariance, &expected) < 1e-15);
        // lag 1: (-2*0 + 0*2) / 8 = 0 and (-1*-1 + -1*2) / 6 = -1/6.
        assert!(s.lag1_autocorrelation[0].abs() < 1e-15);
        assert!((s.lag1_autocorrelation[1] + 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn linear_detrend_removes_a_drifting_bias() {
        let mut rng = Rng::new(11);
        let l = DMatrix::from_diagonal(&DVector::from_vec(vec![0.01, 0.02]));
        let r_true = &l * l.transpose();
        let n = 20_000;
        // The bias drifts by 0.1 rad/s over the segment: five times sigma.
        let drift = [0.1 / n as f64, -0.05 / n as f64];
        let bias = [0.02, -0.01];
        let samples = generate(&mut rng, n, &bias, &l, &drift);
        let lin = estimate_sensor_statistics(
            &samples,
            &NoiseSettings {
                detrend: Detrend::Linear,
                ..Default::default()
            },
        )
        .unwrap();
        for i in 0..2 {
            assert!((lin.drift_per_sample[i] / drift[i] - 1.0).abs() < 0.05);
            // Bias at the middle of the segment.
            let mid = bias[i] + drift[i] * (n as f64 - 1.0) / 2.0;
            assert!((lin.bias[i] - mid).abs() < 4.0 * lin.bias_standard_error[i]);
        }
        assert!(rel_frobenius(&lin.covariance, &r_true) < 0.04);
        // Removing only the mean inflates the variance by drift^2 n^2 / 12
        // and the drift shows as a large lag-one autocorrelation.
        let mean_only = estimate_sensor_statistics(&samples, &NoiseSettings::default()).unwrap();
        let inflated = r_true[(0, 0)] + (0.1f64).powi(2) / 12.0;
        assert!((mean_only.covariance[(0, 0)] / inflated - 1.0).abs() < 0.05);
        assert!(mean_only.lag1_autocorrelation[0] > 0.5);
        assert!(lin.lag1_autocorrelation[0].abs() < 4.0 / (n as f64).sqrt());
    }

    #[test]
    fn quantised_silent_channel_gets_a_floor() {
        let samples: Vec<[f64; 2]> = (0..100).map(|k| [0.5, (k % 2) as f64]).collect();
        let s = estimate_sensor_statistics(&samples, &NoiseSettings::default()).unwrap();
        assert_eq!(s.covariance[(0, 0)], 0.0);
        assert_eq!(s.lag1_autocorrelation[0], 0.0);
        // Alternating 0/1: strongly negative lag-one autocorrelation.
        assert!(s.lag1_autocorrelation[1] < -0.9);
        let r = s.covariance_with_floor(1e-6);
        assert_eq!(r[(0, 0)], 1e-6);
        assert_eq!(r[(1, 1)], s.covariance[(1, 1)]);
        assert!(r.cholesky().is_some());
    }

    #[test]
    fn bad_input_is_refused() {
        let ok = NoiseSettings::default();
        let one = [[1.0, 2.0]];
        assert!(matches!(
            estimate_sensor_statistics(&one, &ok),
            Err(KalmanError::InvalidArgument {
                name: "samples",
                ..
            })
        ));
        let two = [[1.0, 2.0], [1.0, 2.5]];
        let linear = NoiseSettings {
            detrend: Detrend::Linear,
            ..Default::default()
        };
        assert!(estimate_sensor_statistics(&two, &linear).is_err());
        let empty: [[f64; 0]; 3] = [[], [], []];
        assert!(estimate_sensor_statistics(&empty, &ok).is_err());
        let ragged = vec![vec![1.0, 2.0], vec![1.0]];
        assert!(matches!(
            estimate_sensor_statistics(&ragged, &ok),
            Err(KalmanError::DimensionMismatch {
                name: "samples",
                found_cols: 1,
                ..
            })
        ));
        let nan = [[1.0, 2.0], [1.0, f64::NAN], [0.0, 0.0]];
        assert_eq!(
            estimate_sensor_statistics(&nan, &ok),
            Err(KalmanError::NonFinite {
                name: "samples",
                row: 1,
                col: 1
            })
        );
        let inf = [[f64::INFINITY, 2.0], [1.0, 2.0]];
        assert!(estimate_sensor_statistics(&inf, &ok).is_err());
        let wrong_ref = NoiseSettings {
            reference: Some(vec![0.0]),
            ..Default::default()
        };
        assert!(matches!(
            estimate_sensor_statistics(&two, &wrong_ref),
            Err(KalmanError::DimensionMismatch {
                name: "reference",
                ..
            })
        ));
        let nan_ref = NoiseSettings {
            reference: Some(vec![0.0, f64::NAN]),
            ..Default::default()
        };
        assert!(matches!(
            estimate_sensor_statistics(&two, &nan_ref),
            Err(KalmanError::NonFinite {
                name: "reference",
                ..
            })
        ));
    }
}
