//! The plants of the closed loop, sampled at the controller rate: the
//! nonlinear tricopter of kestrel-tricopter-model or a linear rate model,
//! each with the gyro model.

use crate::constants::pwm;
use crate::error::TricopterError;
use kestrel_core::formats::SsModel;
use kestrel_tricopter_model::{GyroConfig, GyroSensor, Plant, PlantConfig, idx};
use nalgebra::{DMatrix, DVector};

/// A tricopter plant sampled at the controller rate: pulses in, gyro out.
pub trait RatePlant {
    /// The gyro sample now (rad/s, with bias and noise).
    fn measure(&mut self) -> [f64; 3];
    /// The true body rates now (rad/s).
    fn rates(&self) -> [f64; 3];
    /// Holds the pulses `[pwm1, pwm2, pwm3, servo]` for one sample.
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), TricopterError>;
}

/// The nonlinear tricopter of kestrel-tricopter-model (RK4, gusts, gyro).
#[derive(Clone, Debug)]
pub struct NonlinearPlant(pub Plant);

impl NonlinearPlant {
    /// The plant in the air at the hover trim with the given body rates
    /// (ground off, so steady rotations do not end on the floor).
    pub fn hovering(
        mut config: PlantConfig,
        rates: [f64; 3],
        seed: u64,
    ) -> Result<Self, TricopterError> {
        config.ground = false;
        let err = |e: kestrel_tricopter_model::ModelError| {
            TricopterError::setting("plant", e.to_string())
        };
        let mut plant = Plant::new(config, seed).map_err(err)?;
        let trim = plant.model().trim_hover().map_err(err)?;
        let mut x = trim.state;
        x[idx::P] = rates[0];
        x[idx::Q] = rates[1];
        x[idx::R] = rates[2];
        plant.set_state(x).map_err(err)?;
        Ok(NonlinearPlant(plant))
    }
}

impl RatePlant for NonlinearPlant {
    fn measure(&mut self) -> [f64; 3] {
        self.0.measure()
    }
    fn rates(&self) -> [f64; 3] {
        let x = self.0.state();
        [x[idx::P], x[idx::Q], x[idx::R]]
    }
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), TricopterError> {
        self.0
            .advance(pwm)
            .map_err(|e| TricopterError::setting("plant", e.to_string()))
    }
}

/// A linear 4-input, 3-output rate model as the plant (e.g. the design
/// model itself, or an identified one), with the gyro of
/// kestrel-tricopter-model.
#[derive(Clone, Debug)]
pub struct LinearPlant {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    x: DVector<f64>,
    u0: DVector<f64>,
    gyro: GyroSensor,
}

impl LinearPlant {
    /// The model's state set so that its outputs are `rates` (least-norm
    /// state `C^+ rates`). Pulses map to inputs as `u = pwm - shift`, where
    /// the shift `[t - t_h, t - t_h, t - t_h, 0]` removes a throttle `t`
    /// away from the model's hover throttle `t_h`.
    pub fn new(
        model: &SsModel,
        rates: [f64; 3],
        gyro: GyroConfig,
        seed: u64,
    ) -> Result<Self, TricopterError> {
        if model.nu() != 4 || model.ny() != 3 {
            return Err(TricopterError::dim(
                "linear plant",
                "4 inputs (pulses) and 3 outputs (rates)",
                format!("{} inputs and {} outputs", model.nu(), model.ny()),
            ));
        }
        let pinv = model
            .c
            .clone()
            .pseudo_inverse(1e-12)
            .map_err(|e| TricopterError::setting("C", e.to_string()))?;
        let trim = crate::problems::tricopter_trim(model)?;
        // The pulses at hover in the model's convention.
        let u0 = match &model.u0 {
            Some(u) if trim.hover_throttle > 0.0 => u.clone(),
            _ => DVector::from_fn(4, |i, _| {
                if i < 3 {
                    trim.offsets[i]
                } else {
                    trim.offsets[3] + pwm::SERVO_CENTER
                }
            }),
        };
        Ok(LinearPlant {
            a: model.a.clone(),
            b: model.b.clone(),
            c: model.c.clone(),
            x: pinv * DVector::from_column_slice(&rates),
            u0,
            gyro: GyroSensor::new(gyro, seed)
                .map_err(|e| TricopterError::setting("gyro", e.to_string()))?,
        })
    }
}

impl RatePlant for LinearPlant {
    fn measure(&mut self) -> [f64; 3] {
        let r = self.rates();
        self.gyro.measure(&r)
    }
    fn rates(&self) -> [f64; 3] {
        let y = &self.c * &self.x;
        [y[0], y[1], y[2]]
    }
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), TricopterError> {
        if pwm.iter().any(|v| !v.is_finite()) {
            return Err(TricopterError::non_finite("pulses"));
        }
        let du = DVector::from_column_slice(pwm) - &self.u0;
        self.x = &self.a * &self.x + &self.b * du;
        Ok(())
    }
}

/// Which plant a closed-loop run flies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PlantKind {
    /// The nonlinear tricopter of kestrel-tricopter-model ([`NonlinearPlant`]).
    #[default]
    Nonlinear,
    /// The design model itself ([`LinearPlant`]), with the same gyro.
    Linear,
}

impl RatePlant for Box<dyn RatePlant> {
    fn measure(&mut self) -> [f64; 3] {
        (**self).measure()
    }
    fn rates(&self) -> [f64; 3] {
        (**self).rates()
    }
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), TricopterError> {
        (**self).advance(pwm)
    }
}
