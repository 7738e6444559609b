//! The sampled plant: the nonlinear model integrated at a fixed step, a gyro
//! sampled at the controller rate, gust torques and flat ground. This is the
//! "flight-test range" any controller (the baseline [`crate::RatePid`], an
//! MPC, the AVR firmware in the loop) can fly.

use crate::error::ModelError;
use crate::model::{Disturbance, Input, NX, State, Tricopter, idx};
use crate::params::Params;
use crate::sensor::{Gust, GustConfig, GyroConfig, GyroSensor};

/// Settings of [`Plant`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// The aircraft.
    pub params: Params,
    /// The gyro (its `rate_hz` is the sample rate of the plant).
    pub gyro: GyroConfig,
    /// Gust torques (held over each sample).
    pub gust: GustConfig,
    /// RK4 integration step (s); must divide the sample period.
    pub dt: f64,
    /// Whether flat ground at altitude 0 holds the aircraft up.
    pub ground: bool,
}

impl Default for PlantConfig {
    /// The default aircraft and gyro, light gusts, 1 kHz integration, ground on.
    fn default() -> Self {
        PlantConfig {
            params: Params::default(),
            gyro: GyroConfig::default(),
            gust: GustConfig::default(),
            dt: 1e-3,
            ground: true,
        }
    }
}

/// A sampled tricopter plant with zero-order-hold inputs.
///
/// ```
/// use kestrel_tricopter_model::{Plant, PlantConfig};
/// let mut plant = Plant::new(PlantConfig::default(), 42).unwrap();
/// let y = plant.measure();                  // gyro sample at t = 0
/// assert!(y.iter().all(|v| v.abs() < 0.05)); // on the ground: bias + noise
/// plant.advance(&[1000.0, 1000.0, 1000.0, 1500.0]).unwrap(); // one 20 ms sample
/// assert!((plant.time() - 0.02).abs() < 1e-12 && !plant.airborne());
/// ```
#[derive(Clone, Debug)]
pub struct Plant {
    model: Tricopter,
    config: PlantConfig,
    gyro: GyroSensor,
    gust: Gust,
    x: State,
    substeps: usize,
    sample: usize,
    on_ground: bool,
}

impl Plant {
    /// A plant at rest on the ground at the origin, motors stopped. The seed
    /// drives the gyro noise and the gusts (two independent streams).
    pub fn new(config: PlantConfig, seed: u64) -> Result<Self, ModelError> {
        let model = Tricopter::new(config.params)?;
        let ts = 1.0 / config.gyro.rate_hz;
        if !(config.dt.is_finite() && config.dt > 0.0) {
            return Err(ModelError::InvalidSetting {
                name: "dt",
                reason: format!("must be finite and positive, found {}", config.dt),
            });
        }
        let ratio = ts / config.dt;
        let substeps = ratio.round();
        if !(substeps >= 1.0 && (ratio - substeps).abs() < 1e-6 * ratio) {
            return Err(ModelError::InvalidSetting {
                name: "dt",
                reason: format!(
                    "must divide the sample period {ts} s into whole steps, found {}",
                    config.dt
                ),
            });
        }
        let gyro = GyroSensor::new(config.gyro, seed)?;
        let gust = Gust::new(config.gust, seed ^ 0x9E37_79B9_7F4A_7C15)?;
        Ok(Plant {
            model,
            config,
            gyro,
            gust,
            x: [0.0; NX],
            substeps: substeps as usize,
            sample: 0,
            on_ground: config.ground,
        })
    }

    /// Replaces the state (e.g. to start at the hover trim in the air).
    pub fn set_state(&mut self, x: State) -> Result<(), ModelError> {
        if !x.iter().all(|v| v.is_finite()) {
            return Err(ModelError::NonFinite { what: "state" });
        }
        self.x = x;
        self.on_ground = self.config.ground && x[idx::Z] >= 0.0 && x[idx::VZ] >= 0.0;
        Ok(())
    }

    /// The true state.
    pub fn state(&self) -> &State {
        &self.x
    }

    /// The model.
    pub fn model(&self) -> &Tricopter {
        &self.model
    }

    /// The settings.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// Time of the current sample (s).
    pub fn time(&self) -> f64 {
        self.sample as f64 * self.sample_time()
    }

    /// Sample period (s).
    pub fn sample_time(&self) -> f64 {
        1.0 / self.config.gyro.rate_hz
    }

    /// Whether the aircraft is off the ground.
    pub fn airborne(&self) -> bool {
        !self.on_ground
    }

    /// The gyro sample of the current true body rates.
    pub fn measure(&mut self) -> [f64; 3] {
        self.gyro
            .measure(&[self.x[idx::P], self.x[idx::Q], self.x[idx::R]])
    }

    /// The gust torque that will act during the next sample (N m, body).
    pub fn gust_torque(&self) -> [f64; 3] {
        self.gust.torque()
    }

    /// Applies `u` (held) for one sample period. On error (non-finite input
    /// or state) the state is left as it was at the failing substep.
    pub fn advance(&mut self, u: &Input) -> Result<(), ModelError> {
        // Gusts do not turn an aircraft resting on the ground.
        let d = Disturbance {
            force: [0.0; 3],
            torque: if self.on_ground {
                [0.0; 3]
            } else {
                self.gust.torque()
            },
        };
        for _ in 0..self.substeps {
            self.model.step_with(&mut self.x, u, &d, self.config.dt)?;
            if self.config.ground {
                self.on_ground = self.model.apply_ground(&mut self.x);
            }
        }
        self.gust.advance(self.sample_time());
        self.sample += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mixer::Mixer;
    use crate::pid::{RatePid, RatePidGains};
    use kestrel_core::ControlLaw;

    /// The baseline rate controller alone (no pilot, through the
    /// `ControlLaw` trait), started at the hover trim with the thesis's noisy
    /// gyro (bias removed as in section 7.2) and gusts, keeps the aircraft
    /// level for 60 s.
    #[test]
    fn rate_pid_alone_holds_hover_for_60_s() {
        let config = PlantConfig::default();
        let mut plant = Plant::new(config, 21).unwrap();
        let trim = plant.model().trim_hover().unwrap();
        let mut x = trim.state;
        x[idx::Z] = -20.0;
        plant.set_state(x).unwrap();
        assert!(plant.airborne());
        let o = trim.offsets;
        let mut pid = RatePid::new(
            RatePidGains::default(),
            Mixer::new([o[0], o[1], o[2], o[3]]),
        );
        let mut u = [0.0; 4];
        let (mut max_tilt, mut sum_r2) = (0.0f64, 0.0);
        for _ in 0..3000 {
            let y = plant.measure();
            let y: Vec<f64> = (0..3).map(|i| y[i] - config.gyro.bias[i]).collect();
            pid.control(&y, &[0.0, 0.0, 0.0, trim.throttle], &mut u)
                .unwrap();
            plant.advance(&u).unwrap();
            let s = plant.state();
            max_tilt = max_tilt
                .max((s[idx::PHI] - trim.phi).abs())
                .max(s[idx::THETA].abs());
            sum_r2 += s[idx::P].powi(2) + s[idx::Q].powi(2);
        }
        assert!(
            max_tilt < 5f64.to_radians(),
            "tilt {}",
            max_tilt.to_degrees()
        );
        assert!((sum_r2 / 6000.0).sqrt() < 0.05);
        assert!(plant.airborne());
        assert!((plant.time() - 60.0).abs() < 1e-9);
    }

    #[test]
    fn bad_settings_are_errors() {
        let c = PlantConfig {
            dt: 0.0015,
            ..PlantConfig::default()
        };
        assert!(Plant::new(c, 0).is_err());
        let mut p = Plant::new(PlantConfig::default(), 0).unwrap();
        assert!(p.set_state([f64::NAN; crate::model::NX]).is_err());
        assert!(p.advance(&[f64::NAN, 1500.0, 1500.0, 1500.0]).is_err());
    }
}
