#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

// clarabel's SDP support needs a LAPACK; link the system OpenBLAS.
#[cfg(feature = "std")]
extern crate openblas_src as _;

pub mod runtime;

pub use runtime::{FgmTables, FgmView, FgmWorkspace, Start, WorkspaceMut, shift_into, solve_view};

#[cfg(feature = "std")]
mod design;
#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod export;
#[cfg(feature = "std")]
mod mpc_law;
#[cfg(feature = "std")]
pub mod precond;
#[cfg(feature = "std")]
mod problem;
#[cfg(feature = "std")]
pub mod reference;

#[cfg(feature = "std")]
pub use design::{
    AppliedInputs, Certificate, FgmData, FgmDesign, FgmSettings, InputTolerance,
    MAX_ITERATION_BOUND, Momentum, MomentumScheme, RecommendedStart, RoundingBound,
    WarmCertificate, WarmStartAssumption,
};
#[cfg(feature = "std")]
pub use error::FgmError;
#[cfg(feature = "std")]
pub use export::{ExportScalar, export_rust};
#[cfg(feature = "std")]
pub use mpc_law::{FastGradientSolver, FgmMpc, FgmOptions, FgmStart};
#[cfg(feature = "std")]
pub use precond::{Preconditioner, Preconditioning, Spectrum};
#[cfg(feature = "std")]
pub use problem::{Bounds, BoxQp};

/// The input tolerance in its eigenvalue form: the `eps` on `J - J*` that keeps every input
/// within `max_error` of the optimum, `eps = mu_H / 2 * max_error^2`
/// (strong convexity: `|z - z*|_inf <= |z - z*|_2 <= sqrt(2 (J - J*) / mu_H)`).
#[cfg(feature = "std")]
pub fn eps_for_input_error(mu_h: f64, max_error: f64) -> f64 {
    0.5 * mu_h * max_error * max_error
}
