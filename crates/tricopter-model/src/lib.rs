#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]
// Index loops mirror the equations (rows, columns, axes) in this numeric code.
#![allow(clippy::needless_range_loop)]

mod mixer;
mod pid;

pub use mixer::{
    C_PITCH, C_ROLL, C_YAW, ESC_PWM_RANGE, MIX_MATRIX, Mixer, MixerOutput, SERVO_PWM_RANGE,
    VirtualInput,
};
pub use pid::{RatePid, RatePidGains};

#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod experiment;
#[cfg(feature = "std")]
mod model;
#[cfg(feature = "std")]
mod params;
#[cfg(feature = "std")]
mod plant;
#[cfg(feature = "std")]
mod reduced;
#[cfg(feature = "std")]
mod sensor;
#[cfg(feature = "std")]
mod trim;

#[cfg(feature = "std")]
pub use error::ModelError;
#[cfg(feature = "std")]
pub use experiment::{
    Experiment, FlightLog, LOG_COLUMNS, LogRow, MAX_SIM_SECONDS, MAX_SIM_STEPS, SimSettings,
    simulate,
};
#[cfg(feature = "std")]
pub use model::{
    Disturbance, INPUT_NAMES, Input, Linearization, NU, NX, NY, OUTPUT_NAMES, Output, STATE_NAMES,
    State, Tricopter, idx, rotation_matrix,
};
#[cfg(feature = "std")]
pub use params::{Params, R_EARTH};
#[cfg(feature = "std")]
pub use plant::{Plant, PlantConfig};
#[cfg(feature = "std")]
pub use reduced::{
    GreyBoxParams, RateInputs, RateModelKind, grey_box_rate_model, rate_model, rate_model_at,
    rate_model_discrete,
};
#[cfg(feature = "std")]
pub use sensor::{
    Gust, GustConfig, GyroConfig, GyroSensor, THESIS_GYRO_BIAS, THESIS_GYRO_COVARIANCE,
};
#[cfg(feature = "std")]
pub use trim::Trim;
