#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

#[cfg(feature = "std")]
mod condense;
#[cfg(feature = "std")]
mod constraints;
#[cfg(feature = "std")]
mod design;
#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod law;
#[cfg(feature = "std")]
mod layout;
#[cfg(feature = "std")]
mod limits;
#[cfg(feature = "std")]
mod lq;
#[cfg(feature = "std")]
mod offset_free;
#[cfg(feature = "std")]
mod polish;
#[cfg(feature = "std")]
mod qp;
#[cfg(feature = "std")]
mod rows;

#[cfg(feature = "std")]
pub use condense::{ModelMatrices, MpcProblem};
#[cfg(feature = "std")]
pub use constraints::{Bounds, BoundsAt, InputTarget, Parameter, SoftPenalty, TerminalSet};
#[cfg(feature = "std")]
pub use design::{Blocking, MpcSettings, Terminal, Weight};
#[cfg(feature = "std")]
pub use error::MpcError;
#[cfg(feature = "std")]
pub use law::{MpcLaw, ParametricQpSolver, QpMpc};
#[cfg(feature = "std")]
pub use layout::ThetaLayout;
#[cfg(feature = "std")]
pub use limits::{
    CondensingCost, MAX_CONDENSING_BYTES, MAX_CONDENSING_FLOPS, MAX_DECISION_VARIABLES, human_bytes,
};
#[cfg(feature = "std")]
pub use offset_free::{DisturbanceModel, OffsetFreeDesign};
#[cfg(feature = "std")]
pub use qp::{KktResiduals, QpSettings, QpSolution, ReferenceSolver, kkt_residuals};
#[cfg(feature = "std")]
pub use rows::{ConstraintKind, RowLabel, Side};
