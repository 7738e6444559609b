//! The gyroscope model of section 7.1.4 and a gust-torque process disturbance.
//!
//! Gyro: `y_k = Q(omega_k + e_0 + e_k^d)`, with `e_0` the constant bias
//! (7.5), `e_k^d ~ N(0, R)` white (7.6) and `Q` rounding to the quantisation
//! step (the thesis's histogram, figure 7.5). The sample covariance of the
//! quantised output is about `R + q^2/12 I` (Sheppard's correction) when the
//! noise spans a few steps. All randomness comes from a seeded
//! xoshiro256++ generator, so a seed reproduces a run exactly.

use crate::error::ModelError;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Gyro bias `e_0` of (7.5) (rad/s).
pub const THESIS_GYRO_BIAS: [f64; 3] = [-9.72e-4, -4.92e-5, 4.27e-3];
/// Gyro noise covariance `R` of (7.6) ((rad/s)^2).
pub const THESIS_GYRO_COVARIANCE: [[f64; 3]; 3] = [
    [1.30e-6, -0.02e-6, -0.06e-6],
    [-0.02e-6, 7.0e-6, -0.24e-6],
    [-0.06e-6, -0.24e-6, 12.67e-6],
];

/// Settings of [`GyroSensor`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroConfig {
    /// Constant bias `e_0` (rad/s).
    pub bias: [f64; 3],
    /// Covariance `R` of the white noise ((rad/s)^2), symmetric positive
    /// semidefinite.
    pub covariance: [[f64; 3]; 3],
    /// Quantisation step (rad/s); 0 disables quantisation.
    pub quantum: f64,
    /// Sample rate (Hz).
    pub rate_hz: f64,
}

impl Default for GyroConfig {
    /// The thesis's (7.5) and (7.6) at 50 Hz, quantised like a 16-bit
    /// +-2000 deg/s gyro (one step = 1/16.4 deg/s = 1.06e-3 rad/s).
    fn default() -> Self {
        GyroConfig {
            bias: THESIS_GYRO_BIAS,
            covariance: THESIS_GYRO_COVARIANCE,
            quantum: (1.0f64 / 16.4).to_radians(),
            rate_hz: 50.0,
        }
    }
}

impl GyroConfig {
    /// A perfect gyro: no bias, no noise, no quantisation.
    pub fn ideal() -> Self {
        GyroConfig {
            bias: [0.0; 3],
            covariance: [[0.0; 3]; 3],
            quantum: 0.0,
            rate_hz: 50.0,
        }
    }
}

/// Lower Cholesky factor of a symmetric positive semidefinite 3x3 matrix.
fn cholesky3(c: &[[f64; 3]; 3]) -> Result<[[f64; 3]; 3], ModelError> {
    let bad = |reason: &str| ModelError::InvalidSetting {
        name: "gyro covariance",
        reason: reason.to_string(),
    };
    if !c.iter().flatten().all(|v| v.is_finite()) {
        return Err(bad("must be finite"));
    }
    let scale = c.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for i in 0..3 {
        for j in 0..3 {
            if (c[i][j] - c[j][i]).abs() > 1e-12 * scale {
                return Err(bad("must be symmetric"));
            }
        }
    }
    let mut l = [[0.0; 3]; 3];
    for j in 0..3 {
        let mut d = c[j][j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if d < -1e-12 * scale {
            return Err(bad("must be positive semidefinite"));
        }
        let d = d.max(0.0).sqrt();
        l[j][j] = d;
        for i in (j + 1)..3 {
            let mut s = c[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = if d > 0.0 { s / d } else { 0.0 };
        }
    }
    Ok(l)
}

/// A sampled gyroscope with bias, correlated Gaussian noise and quantisation.
///
/// ```
/// use kestrel_tricopter_model::{GyroConfig, GyroSensor};
/// let mut a = GyroSensor::new(GyroConfig::default(), 1).unwrap();
/// let mut b = GyroSensor::new(GyroConfig::default(), 1).unwrap();
/// let ya = a.measure(&[0.1, 0.0, -0.2]);
/// assert_eq!(ya, b.measure(&[0.1, 0.0, -0.2]));   // same seed, same noise
/// assert!((ya[0] - 0.1).abs() < 0.01);
/// ```
#[derive(Clone, Debug)]
pub struct GyroSensor {
    config: GyroConfig,
    chol: [[f64; 3]; 3],
    rng: Xoshiro256PlusPlus,
}

impl GyroSensor {
    /// A gyro with the given settings and random seed; errors on a
    /// non-finite bias, a covariance that is not symmetric positive
    /// semidefinite, or a negative quantum / non-positive rate.
    pub fn new(config: GyroConfig, seed: u64) -> Result<Self, ModelError> {
        if !config.bias.iter().all(|v| v.is_finite()) {
            return Err(ModelError::InvalidSetting {
                name: "gyro bias",
                reason: "must be finite".into(),
            });
        }
        if !(config.quantum.is_finite() && config.quantum >= 0.0) {
            return Err(ModelError::InvalidSetting {
                name: "gyro quantum",
                reason: format!("must be finite and >= 0, found {}", config.quantum),
            });
        }
        if !(config.rate_hz.is_finite() && config.rate_hz > 0.0) {
            return Err(ModelError::InvalidSetting {
                name: "gyro rate_hz",
                reason: format!("must be finite and positive, found {}", config.rate_hz),
            });
        }
        let chol = cholesky3(&config.covariance)?;
        Ok(GyroSensor {
            config,
            chol,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
        })
    }

    /// The settings.
    pub fn config(&self) -> &GyroConfig {
        &self.config
    }

    /// One sample for the true body rates `omega` (rad/s).
    pub fn measure(&mut self, omega: &[f64; 3]) -> [f64; 3] {
        let n: [f64; 3] = core::array::from_fn(|_| StandardNormal.sample(&mut self.rng));
        let q = self.config.quantum;
        core::array::from_fn(|i| {
            let e = self.chol[i][0] * n[0] + self.chol[i][1] * n[1] + self.chol[i][2] * n[2];
            let y = omega[i] + self.config.bias[i] + e;
            if q > 0.0 { (y / q).round() * q } else { y }
        })
    }
}

/// Settings of the gust-torque disturbance: a first-order Gauss-Markov
/// torque on each body axis, held over each controller sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GustConfig {
    /// Stationary standard deviation per body axis (N m).
    pub torque_std: [f64; 3],
    /// Correlation time (s).
    pub tau: f64,
}

impl Default for GustConfig {
    /// Light gusts: 0.01 N m on roll and pitch, 0.005 N m on yaw, 0.5 s.
    fn default() -> Self {
        GustConfig {
            torque_std: [0.01, 0.01, 0.005],
            tau: 0.5,
        }
    }
}

impl GustConfig {
    /// No gusts.
    pub fn calm() -> Self {
        GustConfig {
            torque_std: [0.0; 3],
            tau: 0.5,
        }
    }
}

/// The gust-torque process (see [`GustConfig`]).
#[derive(Clone, Debug)]
pub struct Gust {
    config: GustConfig,
    torque: [f64; 3],
    rng: Xoshiro256PlusPlus,
}

impl Gust {
    /// A gust process starting from a stationary random torque.
    pub fn new(config: GustConfig, seed: u64) -> Result<Self, ModelError> {
        if !config.torque_std.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(ModelError::InvalidSetting {
                name: "gust torque_std",
                reason: "must be finite and >= 0".into(),
            });
        }
        if !(config.tau.is_finite() && config.tau > 0.0) {
            return Err(ModelError::InvalidSetting {
                name: "gust tau",
                reason: format!("must be finite and positive, found {}", config.tau),
            });
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let torque = core::array::from_fn(|i| {
            let n: f64 = StandardNormal.sample(&mut rng);
            config.torque_std[i] * n
        });
        Ok(Gust {
            config,
            torque,
            rng,
        })
    }

    /// The current torque (N m, body frame).
    pub fn torque(&self) -> [f64; 3] {
        self.torque
    }

    /// Advances the process by `dt` seconds and returns the new torque.
    pub fn advance(&mut self, dt: f64) -> [f64; 3] {
        let a = (-dt / self.config.tau).exp();
        let b = (1.0 - a * a).sqrt();
        for i in 0..3 {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            self.torque[i] = a * self.torque[i] + b * self.config.torque_std[i] * n;
        }
        self.torque
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_reproduces_the_covariance() {
        let l = cholesky3(&THESIS_GYRO_COVARIANCE).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|k| l[i][k] * l[j][k]).sum();
                assert!((v - THESIS_GYRO_COVARIANCE[i][j]).abs() < 1e-20);
            }
        }
    }

    #[test]
    fn bad_settings_are_errors() {
        let mut c = GyroConfig::default();
        c.covariance[0][1] = 1.0;
        assert!(GyroSensor::new(c, 0).is_err());
        let mut c = GyroConfig::default();
        c.covariance[2][2] = -1.0;
        assert!(GyroSensor::new(c, 0).is_err());
        let mut c = GyroConfig::default();
        c.bias[0] = f64::NAN;
        assert!(GyroSensor::new(c, 0).is_err());
        let c = GyroConfig {
            quantum: -1.0,
            ..GyroConfig::default()
        };
        assert!(GyroSensor::new(c, 0).is_err());
        assert!(
            Gust::new(
                GustConfig {
                    tau: 0.0,
                    ..GustConfig::default()
                },
                0
            )
            .is_err()
        );
    }

    #[test]
    fn ideal_gyro_is_exact_and_quantisation_rounds() {
        let mut g = GyroSensor::new(GyroConfig::ideal(), 3).unwrap();
        assert_eq!(g.measure(&[0.1, -0.2, 0.3]), [0.1, -0.2, 0.3]);
        let mut q = GyroSensor::new(
            GyroConfig {
                quantum: 0.01,
                ..GyroConfig::ideal()
            },
            3,
        )
        .unwrap();
        let y = q.measure(&[0.1234, -0.2251, 0.0]);
        assert!((y[0] - 0.12).abs() < 1e-12 && (y[1] + 0.23).abs() < 1e-12);
    }

    #[test]
    fn gust_has_the_configured_spread() {
        let mut g = Gust::new(GustConfig::default(), 11).unwrap();
        let n = 50_000;
        let mut s2 = [0.0; 3];
        for _ in 0..n {
            let t = g.advance(0.02);
            for i in 0..3 {
                s2[i] += t[i] * t[i];
            }
        }
        for i in 0..3 {
            let sd = (s2[i] / n as f64).sqrt();
            let want = GustConfig::default().torque_std[i];
            // Correlated samples: ~n*dt/(2 tau) = 1000 effective samples, 10 % is > 4 sigma.
            assert!((sd - want).abs() < 0.1 * want, "{sd} vs {want}");
        }
    }
}
