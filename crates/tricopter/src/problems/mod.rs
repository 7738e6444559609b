//! The tricopter's MPC problems: the trim in the thesis's PWM convention
//! ([`TricopterTrim`]), the actuation (trim + move + throttle, saturated),
//! the design models ([`identified_model`], [`design_model`]) and the
//! thesis-sized and larger problems ([`ProblemSize`], [`tricopter_problem`]).

mod models;
mod size;
mod trim;

pub use models::{IDENTIFIED_MODEL_JSON, delay_feedthrough, design_model, identified_model};
pub use size::{ProblemSize, default_weights, tricopter_problem, tricopter_trim};
pub use trim::{Actuation, TricopterTrim, pwm_bounds, throttle_parameter};
