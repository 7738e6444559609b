//! # kestrel-core
//!
//! The `no_std`, allocation-free foundation of the kestrel crates:
//!
//! - [`Scalar`]: the arithmetic the run-time code needs, for `f32`, `f64`
//!   and the saturating fixed-point [`Fixed`] (alias [`Q16`]);
//! - [`Matrix`] and vector kernels ([`dot`], [`axpy`], ...) with const-generic sizes;
//! - the shared state-space traits [`DiscreteLinearModel`],
//!   [`StateEstimator`] and [`ControlLaw`], and the array-backed [`StateSpace`];
//! - the small `Copy` [`Error`].
//!
//! With the default `std` feature it also offers design-time helpers:
//! nalgebra conversions, zero-order-hold discretisation [`c2d`],
//! eigenvalues that always return ([`eig`]: iteration limit, error value
//! on non-convergence), and the JSON interchange [`formats`]
//! (`kestrel.ss.v1`, `kestrel.mpqp.v1`).
//!
//! ```
//! use kestrel_core::{Matrix, Scalar, StateSpace, Q16};
//! // The same model stepped in f64 and in fixed point.
//! let m = StateSpace::new(
//!     Matrix::from_rows([[0.9, 0.1], [0.0, 0.8]]), Matrix::from_rows([[0.0], [1.0]]),
//!     Matrix::from_rows([[1.0, 0.0]]), Matrix::from_rows([[0.0]]), 0.02);
//! let q = StateSpace::<Q16, 2, 1, 1>::from_model(&m).unwrap();
//! let x = m.step(&[1.0, 1.0], &[0.5]);
//! let xq = q.step(&[Q16::ONE, Q16::ONE], &[Q16::from_f64(0.5)]);
//! assert!((x[1] - xq[1].to_f64()).abs() < 1e-4);
//! ```
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
