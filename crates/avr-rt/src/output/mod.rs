//! Output limits, saturation and the failsafe.
//!
//! # The failsafe
//!
//! Once per control period [`Failsafe::on_tick`] is told whether a fresh,
//! valid command frame arrived since the previous tick:
//!
//! - a valid command with finite values: run the controller (after a failsafe
//!   the loop is told to restart its estimator and integrators: *recovery*);
//! - no valid frame this period, the first time: hold the previous outputs;
//! - no valid frame for **two** periods in a row (dropped or corrupted
//!   frames), or any **non-finite** value (in the command or in the
//!   controller's result), or a gyro reading the loop's sensor check
//!   refuses (`control::GyroCheck`: an axis stuck at one value or at full
//!   scale): output the [`SafeOutput`] (by default motors at
//!   1000 us, i.e. stopped, and the servo centred at 1500 us) until a valid
//!   frame comes.
//!
//! Whatever happens, [`PwmLimits::saturate`] keeps the ESC pulses within
//! 1000-2000 us and the servo pulse within 1200-1800 us (thesis section 2.1.2).
//!
//! [`RtScalar`], the scalar conversions of the loop, is here too (file
//! `scalar`), with `limits` and `failsafe`.

mod failsafe;
mod limits;
mod scalar;
#[cfg(test)]
mod tests;

pub use failsafe::{Decision, Failsafe, FailsafeReason};
pub use limits::{PwmLimits, SafeOutput};
pub use scalar::RtScalar;
