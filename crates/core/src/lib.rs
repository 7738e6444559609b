#![doc = include_str!("../README.md")]
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(any(test, feature = "std"))]
extern crate std;

mod error;
mod matrix;
mod model;
mod scalar;

#[cfg(feature = "std")]
pub mod eig;
#[cfg(feature = "std")]
pub mod formats;
#[cfg(feature = "std")]
mod linalg;

pub use error::{Error, check_len};
pub use matrix::{Matrix, add, all_finite, axpy, clamp, dot, scale, sub};
pub use model::{ControlLaw, DiscreteLinearModel, StateEstimator, StateSpace};
pub use scalar::{Fixed, Q16, Scalar};

#[cfg(feature = "std")]
pub use linalg::{Discretized, c2d};
