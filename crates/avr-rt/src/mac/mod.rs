//! [`Q16Mac`]: Q15.16 fixed point with the same values, rounding and
//! saturation as [`kestrel_core::Q16`], whose 32 x 32 -> 64-bit products are
//! written with the ATmega2560's hardware `MUL` (16 byte products in inline
//! assembly) instead of LLVM's generic 64 x 64-bit multiply.
//!
//! It implements [`Scalar`](kestrel_core::Scalar), so every run-time kernel generic over the
//! scalar (Kalman step, tree walk, fast gradient, the rate loop) runs on it
//! unchanged; the firmware selects it with its `fixed-mac` feature, and
//! checks it against `Q16` on the target at boot ([`self_test`]).
//!
//! The 16-bit-coefficient kernels of the `kalman16` and `fgm16` modules
//! are here too: [`dot_q16_i16`], [`row_q16_i16`] (one
//! rounded, saturated row of Q15.16 values and `i16` coefficients) and the
//! routine behind [`Row16::apply_all`]/[`Row16::add_all`] that runs every row
//! of a table in one call, all AVR assembly checked at boot against plain
//! 64-bit arithmetic, plus the saturating sums [`add_sat_i32`] and
//! [`sub_sat_i32`].
//!
//! ```
//! use kestrel_avr_rt::mac::Q16Mac;
//! use kestrel_core::{Scalar, Q16};
//! let (a, b) = (1.75, -3.25);
//! let fast = Q16Mac::from_f64(a) * Q16Mac::from_f64(b);
//! let core = Q16::from_f64(a) * Q16::from_f64(b);
//! assert_eq!(fast.to_bits(), core.to_bits());
//! ```
//!
//! One file per operation: `q16mac` (the type), `arith` (its operators,
//! `Scalar` and `RtScalar`), `mul_wide` (the 64-bit product), `dot_wide`
//! (its dot product), `dot16`, `row` and `row16` (the 16-bit-coefficient
//! kernels and their row type), `rows` (the AVR routine for a whole
//! table), `sat` (saturating sums) and `self_test`. Each holds the AVR
//! assembly and the portable Rust of its operation side by side.

mod arith;
mod dot16;
mod dot_wide;
mod mul_wide;
mod q16mac;
mod row;
mod row16;
#[cfg(target_arch = "avr")]
mod rows;
mod sat;
mod self_test;

pub use dot16::dot_q16_i16;
pub use q16mac::Q16Mac;
pub use row::row_q16_i16;
pub use row16::Row16;
pub(crate) use row16::sat_i32;
pub use sat::{add_sat_i32, sub_sat_i32};
pub use self_test::self_test;
