#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]
// Numerical kernels index several arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

#[cfg(feature = "std")]
mod armax;
#[cfg(feature = "std")]
mod arx;
#[cfg(feature = "std")]
mod closed_loop;
#[cfg(feature = "std")]
mod data;
#[cfg(feature = "std")]
mod delay;
#[cfg(feature = "std")]
mod error;
#[cfg(feature = "std")]
mod feedback;
#[cfg(feature = "std")]
mod filter;
#[cfg(feature = "std")]
mod fit;
#[cfg(feature = "std")]
pub mod linalg;
#[cfg(feature = "std")]
pub mod lm;
#[cfg(feature = "std")]
mod model;
#[cfg(feature = "std")]
mod n4sid;
#[cfg(feature = "std")]
mod pem;
#[cfg(feature = "std")]
mod reduce;
#[cfg(feature = "std")]
pub mod synthetic;
#[cfg(feature = "std")]
mod validate;
#[cfg(feature = "std")]
pub mod workflow;

#[cfg(feature = "std")]
pub use armax::{ArmaxModel, ArmaxSettings, armax};
#[cfg(feature = "std")]
pub use arx::{
    ArxBaseline, ArxBaselineCandidate, ArxBaselineRow, ArxModel, ArxSettings, MAX_ARX_OPERATIONS,
    arx, arx_baseline,
};
#[cfg(feature = "std")]
pub use closed_loop::{
    ArxReduction, ArxReductionSettings, MAX_REALISATION, PBSID_PAST, PbsidResult, PbsidSettings,
    arx_reduction, pbsid, stabilise_a,
};
#[cfg(feature = "std")]
pub use data::{CsvColumns, Experiment, IoData, Offsets, SignalSelection, TimeInterval, TimeUnit};
#[cfg(feature = "std")]
pub use delay::{DelayEstimate, DelaySettings, estimate_delay};
#[cfg(feature = "std")]
pub use error::{Result, SizedMethod, SysidError};
#[cfg(feature = "std")]
pub use feedback::{FTest, FeedbackSettings, FeedbackTest, InputFeedback, feedback_test};
#[cfg(feature = "std")]
pub use filter::{Biquad, Butterworth, Periodogram, periodogram};
#[cfg(feature = "std")]
pub use model::{InnovationModel, OneStepPrediction};
#[cfg(feature = "std")]
pub use n4sid::{
    MAX_HANKEL_BYTES, MAX_ORDER, MatrixEstimate, N4sidResult, N4sidSettings, Weighting,
    model_parameters, n4sid, suggest_order,
};
#[cfg(feature = "std")]
pub use pem::{
    Criterion, Focus, Identified, MAX_PEM_FLOPS_PER_ITERATION, MAX_PEM_JACOBIAN_BYTES, PemResult,
    PemSettings, StopReason, pem, pem_n4sid,
};
#[cfg(feature = "std")]
pub use reduce::{
    BalredSettings, Reduced, ReductionMethod, ZERO_RANK_TOLERANCE, Zero, balred,
    hankel_singular_values, is_transmission_zero, rosenbrock_singular_values, transmission_zeros,
};
#[cfg(feature = "std")]
pub use validate::{
    BaselineComparison, Comparison, FitRow, Horizon, OutputResiduals, Predictor, ResidualAnalysis,
    ValidationReport, compare, estimate_x0_predictor, estimate_x0_simulation, fit_percent,
    persistence_fit, predict_fit, resid, validate,
};
