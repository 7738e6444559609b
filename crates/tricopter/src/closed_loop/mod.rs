//! The closed loop of section 7.7: a tricopter plant (the nonlinear model
//! of kestrel-tricopter-model or a linear model), the gyro, a state
//! estimator, any control law or the baseline PI, the actuation with
//! saturation, and a trace with the cost of every step.
//!
//! One call per run: [`fly_mpc`], [`fly_offset_free`], [`fly_pi`] with
//! [`RunSettings`] (default: the 7.7.1 step in calm air;
//! [`RunSettings::noisy`] for figures 7.18-7.21) returning a [`RunResult`]
//! (trace and [`StepMetrics`]). The MPC runs take the Kalman filter they
//! fly as an argument ([`kalman_design`] is the thesis's).

mod estimator;
mod fly;
mod plant;
mod run;
mod scenario;
mod settings;
mod trace;

pub use estimator::{
    kalman_design, kalman_design_with_disturbance, thesis_disturbance_noise, thesis_noise,
};
pub use fly::{MAX_STATES, RunResult, fly_mpc, fly_offset_free, fly_pi};
pub use plant::{LinearPlant, NonlinearPlant, PlantKind, RatePlant};
pub use run::{run_mpc, run_pid};
pub use scenario::{ReferenceStep, Scenario};
pub use settings::RunSettings;
pub use trace::{DIVERGENCE_MIN_BOUND, StepMetrics, Trace, TraceRow};

#[cfg(test)]
mod tests;
