#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

mod stationary;

#[cfg(feature = "std")]
pub mod augment;
#[cfg(feature = "std")]
mod dare;
#[cfg(feature = "std")]
mod design;
#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod lqr;
#[cfg(feature = "std")]
pub mod noise;
#[cfg(feature = "std")]
mod tv;

pub use stationary::{FilterStatus, StationaryFilter, StationaryGains};

#[cfg(feature = "std")]
pub use augment::{AugmentedModel, Disturbance, DisturbanceDesign, DisturbanceNoise};
#[cfg(feature = "std")]
pub use dare::{DareSettings, DareSolution, DetectabilityCheck, dare, dare_with};
#[cfg(feature = "std")]
pub use design::{KalmanDesign, NoiseModel};
#[cfg(feature = "std")]
pub use error::KalmanError;
#[cfg(feature = "std")]
pub use lqr::{Dlqe, Lqr, dlqe, dlqe_with, dlqr, dlqr_with};
#[cfg(feature = "std")]
pub use tv::TimeVaryingFilter;

#[cfg(test)]
mod augment_tests;
#[cfg(test)]
mod dare_tests;
#[cfg(test)]
mod filter_tests;
#[cfg(test)]
mod testutil;
