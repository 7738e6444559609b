//! Run-time point location and evaluation (`no_std`, no allocation, no panic).
//!
//! The explicit law is stored as flat tables read through [`TreeTables`],
//! so they can live in RAM ([`SliceTables`] over `static` arrays, as the
//! exported Rust source defines them) or be served from the AVR's program
//! memory by an accessor that implements the trait with `lpm` reads.
//!
//! Tables (with `p` parameters and `k` outputs):
//! - nodes `[row a, row b, child if a(theta) <= b(theta), child otherwise]`
//!   where `a` and `b` are affine rows ([`NO_ROW`] for `b` = 0): a region
//!   facet of a box-constrained MPC is "output j's law reaches its bound",
//!   the difference of two rows already stored, so most hyperplanes cost no
//!   numbers at all; a child with the [`LEAF`] bit set is a leaf holding a
//!   law index, others are node indices; the root is a child code too;
//! - laws, `k` row indices each (one affine row per output);
//! - affine rows, `p + 1` numbers each: gains then constant (laws share rows:
//!   a saturated output is the same row in many laws);
//! - the explored set `hull`, rows `a, b` with `a'theta <= b`, the parameter
//!   box, and per output the rows of an affine lower and upper bound
//!   ([`NO_ROW`] if none).
//!
//! Outside the explored set the evaluation is defined and safe: `theta` is
//! first projected onto the parameter box (clamped), the tree gives the law
//! of the region containing that point — the nearest region when the
//! explored set is the box — and the outputs are clamped to their bounds
//! evaluated there; [`Evaluation::outside`] flags it. Outputs are clamped
//! to their bounds in every case (inside the explored set the law already
//! satisfies them, up to rounding).
//!
//! The files: the index types and codes (`index`), the tables and their
//! accessor trait (`tables`), the evaluation (`evaluate`), and the
//! candidate-list point location (`lists`, [`evaluate_lists`]).

mod evaluate;
mod index;
mod lists;
mod tables;
#[cfg(test)]
mod tests;

pub use evaluate::{Evaluation, evaluate, evaluate_with};
pub use index::{LEAF, NO_ROW, TreeIndex, WIDE_LEAF, WIDE_NO_ROW};
pub use lists::{ListAccess, ListEvaluation, ListSlices, evaluate_lists};
pub use tables::{CompactNode, ForestTables, NO_ROW8, SliceTables, TreeTables, WideSliceTables};
