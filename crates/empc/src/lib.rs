#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

pub mod eval;

#[cfg(feature = "std")]
pub mod certify;

#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
pub mod export;
#[cfg(feature = "std")]
pub mod locate;
#[cfg(feature = "std")]
mod lp;
#[cfg(feature = "std")]
mod mpc_law;
#[cfg(feature = "std")]
pub mod mpqp;
#[cfg(feature = "std")]
mod qp;
#[cfg(feature = "std")]
mod rng;
#[cfg(feature = "std")]
pub mod testing;
#[cfg(feature = "std")]
pub mod tree;

pub use eval::{
    CompactNode, Evaluation, ForestTables, LEAF, ListAccess, ListEvaluation, ListSlices, NO_ROW,
    NO_ROW8, SliceTables, TreeIndex, TreeTables, WIDE_LEAF, WIDE_NO_ROW, WideSliceTables, evaluate,
    evaluate_lists, evaluate_with,
};

#[cfg(feature = "std")]
pub use error::EmpcError;
#[cfg(feature = "std")]
pub use locate::{LocateMethod, LocateSettings, Locator, build_locator};
#[cfg(feature = "std")]
pub use mpc_law::{ExplicitMpc, ExplicitSolver};
#[cfg(feature = "std")]
pub use mpqp::{
    CriticalRegion, MpqpSolution, Settings, SolveStats, brute_force_active_sets, solve,
};
#[cfg(feature = "std")]
pub use tree::{
    AnyController, AnyTables, CompactController, CompactTables, DEFAULT_MAX_NODES,
    ExplicitController, Outputs, OwnedTables, TreeLayout, TreeSettings, TreeStats, WideTables,
    build_any, build_compact, build_controller,
};
