#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

pub mod eval;

#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod lp;
#[cfg(feature = "std")]
pub mod mpqp;
#[cfg(feature = "std")]
pub mod testing;
#[cfg(feature = "std")]
mod qp;

pub use eval::{Evaluation, SliceTables, TreeTables, evaluate};

#[cfg(feature = "std")]
pub use error::EmpcError;
#[cfg(feature = "std")]
pub use mpqp::{CriticalRegion, MpqpSolution, Settings, SolveStats, brute_force_active_sets, solve};
