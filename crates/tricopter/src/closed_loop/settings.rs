//! Settings of a closed-loop run: the scenario, the plant and its
//! configuration, the seed.

use crate::closed_loop::plant::{LinearPlant, NonlinearPlant, PlantKind, RatePlant};
use crate::closed_loop::scenario::Scenario;
use crate::error::TricopterError;
use kestrel_core::formats::SsModel;
use kestrel_tricopter_model::{GyroConfig, PlantConfig};

/// Settings of a closed-loop run ([`fly_mpc`](crate::closed_loop::fly_mpc), [`fly_offset_free`](crate::closed_loop::fly_offset_free), [`fly_pi`](crate::closed_loop::fly_pi)).
#[derive(Clone, Debug, PartialEq)]
pub struct RunSettings {
    /// Initial rates, references and their steps, throttle, duration.
    pub scenario: Scenario,
    /// The plant.
    pub plant: PlantKind,
    /// The nonlinear plant's configuration (aircraft, gyro, gusts); the
    /// linear plant uses its gyro.
    pub config: PlantConfig,
    /// Seed of the gyro noise and the gusts.
    pub seed: u64,
}

impl Default for RunSettings {
    /// The step scenario of 7.7.1 on the nonlinear plant in calm air with
    /// an ideal gyro (no bias, no noise), seed 1.
    fn default() -> Self {
        RunSettings {
            scenario: Scenario::thesis_step(),
            plant: PlantKind::Nonlinear,
            config: PlantConfig {
                gyro: GyroConfig::ideal(),
                gust: kestrel_tricopter_model::GustConfig::calm(),
                ..PlantConfig::default()
            },
            seed: 1,
        }
    }
}

impl RunSettings {
    /// The noisy runs of figures 7.18-7.21: the thesis's gyro noise and
    /// bias (7.5)-(7.6) and kestrel-tricopter-model's default gusts.
    pub fn noisy() -> Self {
        RunSettings {
            config: PlantConfig::default(),
            ..RunSettings::default()
        }
    }

    /// The plant of these settings for `model` (the linear plant flies
    /// the model itself), in the air at the scenario's initial rates.
    pub fn plant(&self, model: &SsModel) -> Result<Box<dyn RatePlant>, TricopterError> {
        let rates = self.scenario.initial_rates;
        Ok(match self.plant {
            PlantKind::Nonlinear => {
                Box::new(NonlinearPlant::hovering(self.config, rates, self.seed)?)
            }
            PlantKind::Linear => {
                Box::new(LinearPlant::new(model, rates, self.config.gyro, self.seed)?)
            }
        })
    }
}
