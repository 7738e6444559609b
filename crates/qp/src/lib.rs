#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

mod error;
mod iterate;
#[cfg(feature = "mpc")]
mod mpc_law;
#[cfg(feature = "std")]
pub mod parametric;
mod settings;
mod solver;

pub use error::QpError;
#[cfg(feature = "mpc")]
pub use mpc_law::{ActiveSetMpc, ActiveSetSolver};
pub use settings::QpSettings;
pub use solver::{
    ActiveConstraint, QpData, QpScalar, QpSolver, Side, SolveInfo, Start, index_len, scalar_len,
};

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_kkt;
