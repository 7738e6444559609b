#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

#[cfg(feature = "std")]
mod dare;
#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod lqr;

#[cfg(feature = "std")]
pub use dare::{DareSettings, DareSolution, DetectabilityCheck, dare, dare_with};
#[cfg(feature = "std")]
pub use error::KalmanError;
#[cfg(feature = "std")]
pub use lqr::{Dlqe, Lqr, dlqe, dlqe_with, dlqr, dlqr_with};

#[cfg(test)]
mod dare_tests;
#[cfg(test)]
mod testutil;
