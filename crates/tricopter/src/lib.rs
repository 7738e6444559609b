#![doc = include_str!("../README.md")]

pub mod closed_loop;
pub mod codegen;
pub mod constants;
mod error;
pub mod firmware;
pub mod ident;
pub mod pipeline;
pub mod problems;

pub use error::TricopterError;
pub use problems::{
    Actuation, IDENTIFIED_MODEL_JSON, ProblemSize, TricopterTrim, default_weights,
    delay_feedthrough, design_model, identified_model, throttle_parameter, tricopter_problem,
    tricopter_trim,
};
