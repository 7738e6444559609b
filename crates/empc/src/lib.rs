#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

pub mod eval;

#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
pub mod export;
#[cfg(feature = "std")]
mod lp;
#[cfg(feature = "std")]
pub mod mpqp;
#[cfg(feature = "std")]
mod qp;
#[cfg(feature = "std")]
pub mod testing;
#[cfg(feature = "std")]
pub mod tree;

pub use eval::{
    CompactNode, Evaluation, ForestTables, LEAF, NO_ROW, NO_ROW8, SliceTables, TreeTables,
    evaluate, evaluate_with,
};

#[cfg(feature = "std")]
pub use error::EmpcError;
#[cfg(feature = "std")]
pub use mpqp::{
    CriticalRegion, MpqpSolution, Settings, SolveStats, brute_force_active_sets, solve,
};
#[cfg(feature = "std")]
pub use tree::{
    CompactController, CompactTables, ExplicitController, Outputs, OwnedTables, TreeSettings,
    TreeStats, build_compact, build_controller,
};
