//! [`Qp16Solver`]: kestrel-qp's dual active-set method for box-constrained
//! parametric QPs in fixed point on precomputed tables, for the AVR.
//!
//! The problem `min 1/2 z'Hz + q(theta)'z` s.t. `lb(theta) <= z <= ub(theta)`
//! (`q`, `lb`, `ub` affine in theta: the condensed MPC with input bounds)
//! is solved with the decision rules of `kestrel_qp::QpSolver` (cold start
//! from the empty set; the most violated bound enters; a wrong-sign
//! multiplier blocks the dual step, the strictly smallest step wins and its
//! bound leaves; the LDL' factor of `M = (H^-1)_AA` is updated on every
//! add and remove, never recomputed), on tables built offline
//! ([`Qp16Tables`], by `Qp16Tables::from_mpqp` with the `std` feature):
//!
//! - `H^-1` scaled (`P = 2^f H^-1 / 4^s`, Q15.16), so `M` needs no
//!   factorisation of `H` at run time: an active bound adds one row of
//!   `M` straight from `P`;
//! - the unconstrained solution `w_unc = K theta + k0` as 16-bit rows
//!   (the high and low halves of 32-bit coefficients with their own binary
//!   point, `mac::Row16`, all rows in two calls of the AVR rows routine)
//!   and the bounds as affine rows ([`Row32`]: sums only for a bound that
//!   moves with the throttle);
//! - the state (multipliers, factor, point) in `i32` with fraction bits
//!   chosen offline per quantity, every product an exact sum of 32 x 32-bit
//!   products rounded once (the hardware multiplier, one assembly kernel
//!   per sum), divisions only
//!   for the factor's pivots (one per new pivot, shift and subtract) and
//!   for a blocking step.
//!
//! All arithmetic is integer with a defined rounding, so the host runs the
//! same code with the same bits (the host emulation is this module). The
//! variables are scaled by a common power of two (`w = z / 2^s`), which
//! keeps the most-violated comparison in the problem's own units; the
//! exactness of the answer is the active set it identifies: with the same
//! final active set as the f64 solver, `z` differs from it only by the
//! Q15.16 rounding (see docs/avr-qp.md for the measured bound).
//!
//! ```
//! use kestrel_avr_rt::qp16::{Qp16Solver, Qp16Start, Qp16Tables, Row32};
//! // One variable, theta = [r]: min 1/2 z^2 - r z on [-1, 1] (z = clamp(r)).
//! use kestrel_avr_rt::mac::Row16;
//! let t = Qp16Tables::<1, 1> {
//!     hinv: [[65_536]],
//!     unc_hi: [Row16::new([1], 0, 0)], // w_unc = theta
//!     unc_lo: [Row16::new([0], 16, 1)],
//!     unc0: [0],
//!     lb: [Row32::constant(-65_536)],
//!     ub: [Row32::constant(65_536)],
//!     var_shift: 0, obj_shift: 0, p_bits: 16, l_bits: 16, nu_bits: 16, pivot_bits: 4,
//!     primal_tol: 2, dual_tol: 2, max_iterations: 10,
//! };
//! let mut s = Qp16Solver::<1>::new();
//! s.solve(&t, &[32_768], Qp16Start::Cold).unwrap();
//! assert_eq!(s.solution()[0], 32_768); // 0.5
//! let info = s.solve(&t, &[3 * 65_536], Qp16Start::Cold).unwrap();
//! assert_eq!((s.solution()[0], info.iterations), (65_536, 1)); // the bound
//! ```

mod arith;
#[cfg(target_arch = "avr")]
mod avr;
#[cfg(feature = "std")]
mod build;
pub mod probe;
mod sets;
#[cfg(target_arch = "avr")]
mod sets_avr;
mod solver;
mod tables;

pub use arith::{Recip, mac_round, mul_round, rows_round};
#[cfg(feature = "std")]
pub use build::{BoxQp, Qp16BuildError, Qp16Scaling, Qp16Settings, box_form, theta_q16};
pub use sets::{Qp16SetSolver, Qp16SetTables};
#[cfg(all(target_arch = "avr", feature = "qp16-profile"))]
pub use solver::QP16_PROFILE;
pub use solver::{Qp16Error, Qp16Info, Qp16Solver, Qp16Start};
pub use tables::{Qp16Tables, Row32};

#[cfg(test)]
mod tests;
