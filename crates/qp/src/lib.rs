#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

mod error;
mod iterate;
#[cfg(feature = "std")]
pub mod parametric;
mod settings;
mod solver;

pub use error::QpError;
pub use settings::QpSettings;
pub use solver::{
    ActiveConstraint, QpData, QpScalar, QpSolver, Side, SolveInfo, Start, index_len, scalar_len,
};

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_kkt;
