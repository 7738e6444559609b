//! The firmware's fast explicit MPC: kestrel-empc's search tree with its
//! affine rows quantised to 16 bits, evaluated on the AVR's hardware
//! multiplier with the rows read straight from flash (`ELPM Z+`).
//!
//! What makes it fast (against `explicit::FlashTree`'s generic walk):
//!
//! - `theta` is quantised once per period to `i16` (parameter `j` with its
//!   own binary point, so its box fills 16 bits) and projected onto the box;
//! - every affine row (laws, output bounds; the tree's hyperplanes are
//!   differences of two of them) holds `i16` gains in one common scale
//!   `2^K` of the output and an `i32` constant, and is evaluated by one
//!   assembly kernel (four hardware `MUL`s per term, a 32-bit accumulator;
//!   the design proves the sum cannot overflow on the box);
//! - a row is evaluated at most once per period (a value cache in RAM,
//!   stamped with the period), so a node comparing "output i's law" with
//!   "its bound" costs two cached reads after the first time, and the
//!   leaf's law rows usually come for free;
//! - rows store only their columns from the first non-zero one (the
//!   tricopter's output bounds depend on the throttle alone: one term).
//!
//! Byte layout ([`Tree16Layout`], little-endian), in this order:
//! - parameters, 5 bytes each: the right shift `s` (`i8`) from Q15.16 to the
//!   parameter's `i16` units, the box `lb`, `ub` (`i16`, in those units);
//! - nodes in preorder, 5 bytes each: rows `a`, `b` (`u8`, `b` = [`NONE`]
//!   for zero), the child if `a <= b` (`u8`: [`NONE`] for the next node,
//!   otherwise a law index), the other child (`u16`: [`LEAF`] `|` law, or a
//!   node index);
//! - laws, `NU` row indices (`u8`) each;
//! - output bounds, rows of the lower and upper bound (`u8`, [`NONE`]: none);
//! - rows, [`Tree16Layout::row_bytes`] each: first column `start` (`u8`),
//!   constant (`i32`), gains (`i16`) of columns `start..P`, then zeros.
//!
//! `explicit::quantize` (design time) writes the table from
//! kestrel-empc's tree and checks it against the f64 evaluation.
//!
//! ```
//! use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16, Tree16Layout, LEAF, NONE};
//! use kestrel_core::ControlLaw;
//! // One parameter theta in [-1, 1] (Q15.16 >> 1: 2^15 units per 1),
//! // one output: z = -theta for theta <= 0, 0 otherwise, in units of 2^-16.
//! let layout = Tree16Layout { n_params: 1, n_outputs: 1, n_nodes: 1, n_laws: 2, n_rows: 3, root: 0, scale: 16, wide: false };
//! let mut b = vec![1u8];
//! b.extend((-32767i16).to_le_bytes());
//! b.extend(32767i16.to_le_bytes());
//! b.extend([2, NONE, 0]);                // theta <= 0: law 0
//! b.extend((LEAF | 1).to_le_bytes());    // otherwise law 1
//! b.extend([0, 1, NONE, NONE]);          // laws (rows 0, 1), no output bounds
//! for (c0, g) in [(0i32, -2i16), (0, 0), (0, 2)] { // -theta, 0, theta
//!     b.push(0);
//!     b.extend(c0.to_le_bytes());
//!     b.extend(g.to_le_bytes());
//! }
//! let tree = Tree16::new(&b[..], layout).unwrap();
//! let mut law = Empc16Law::<f32, _, 1, 1, 3>::new(tree, 0).unwrap();
//! let mut u = [0.0f32];
//! law.control(&[], &[-0.5], &mut u).unwrap();
//! assert_eq!(u, [0.5]);
//! law.control(&[], &[0.25], &mut u).unwrap();
//! assert_eq!(u, [0.0]);
//! ```
//!
//! One file per step: `layout` (the byte layout), `table` (the accessor,
//! row values, the index check), `law` (the law's state and
//! construction), `walk` (the period in Rust), `asm` and `walk_avr` (the
//! period in AVR assembly), `ctx` (the assembly's context block), `solve`
//! (the period as a `ControlLaw`), `check` (test instrumentation).

#[cfg(target_arch = "avr")]
mod asm;
mod check;
mod ctx;
mod law;
mod layout;
mod solve;
mod table;
#[cfg(test)]
mod tests;
mod walk;
#[cfg(target_arch = "avr")]
mod walk_avr;

pub use law::{Empc16Law, Raw};
pub use layout::{LEAF, NONE, NONE16, Tree16Layout};
pub use table::Tree16;
