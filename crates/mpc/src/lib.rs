#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]

#[cfg(feature = "std")]
mod condense;
#[cfg(feature = "std")]
mod design;
#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod law;
#[cfg(feature = "std")]
mod lq;
#[cfg(feature = "std")]
mod offset_free;
#[cfg(feature = "std")]
mod qp;
#[cfg(feature = "std")]
pub mod sim;
#[cfg(feature = "std")]
mod solvers;
#[cfg(feature = "std")]
mod tricopter;

#[cfg(feature = "std")]
pub use condense::{ModelMatrices, MpcProblem, ThetaLayout};
#[cfg(feature = "std")]
pub use design::{
    Blocking, BoundsAt, InputBounds, MpcSettings, Terminal, ThrottleParameter, Weight, pwm,
};
#[cfg(feature = "std")]
pub use error::MpcError;
#[cfg(feature = "empc")]
pub use law::ExplicitMpc;
#[cfg(feature = "fgm")]
pub use law::FgmMpc;
#[cfg(feature = "std")]
pub use law::{MpcLaw, ParametricQpSolver, QpMpc};
#[cfg(feature = "std")]
pub use offset_free::{DisturbanceModel, OffsetFreeDesign};
#[cfg(feature = "std")]
pub use qp::{KktResiduals, QpSettings, QpSolution, ReferenceSolver, kkt_residuals};
#[cfg(feature = "empc")]
pub use solvers::ExplicitSolver;
#[cfg(feature = "fgm")]
pub use solvers::{FastGradientSolver, FgmOptions, FgmStart};
#[cfg(feature = "std")]
pub use tricopter::{
    Actuation, IDENTIFIED_MODEL_JSON, ProblemSize, TricopterTrim, default_weights,
    delay_feedthrough, design_model, identified_model, tricopter_problem, tricopter_trim,
};
