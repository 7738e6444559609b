//! Point location that grows with the regions (design time): a shallow
//! tree over facet hyperplanes whose leaves list a few candidate regions,
//! each tested by its own facets ([`build_lists`], evaluated by the
//! `no_std` [`evaluate_lists`](crate::eval::evaluate_lists)), or the exact
//! search tree of [`crate::tree`] where it is small ([`build_locator`]
//! chooses; [`estimate`] tells the size before building).
//!
//! - Laws are shared as in [`crate::tree`] (first move, identical rows
//!   and laws stored once).
//! - Every facet hyperplane is stored once (`pool`): where two regions
//!   with different laws meet, the (continuous) laws agree on the facet,
//!   so the hyperplane is the difference of two stored law rows and costs
//!   two indices; only the others get a row. Facets on the parameter box
//!   or the explored set's hull are dropped (the evaluation projects onto
//!   the box and flags points outside the hull first).
//! - The tree (`split`) splits a cell by one of its regions' facets until
//!   at most [`LocateSettings::leaf_regions`] regions with another law
//!   than the leaf's final law meet it; a region is kept in a child when
//!   an LP finds a point of it there, so the regions of a leaf cover its
//!   cell and the answer is exact.
//!
//! One file per concept: `settings` (and the progress reports), `stats`,
//! `tables` (owned tables and index widths), `json` (reading, writing and
//! checking them), `source` (Rust source), `pool`, `split`, `build`.

mod build;
mod json;
mod pool;
mod settings;
mod source;
mod split;
mod stats;
mod tables;
#[cfg(test)]
mod tests;

pub use build::{ListController, Locator, build_lists, build_locator, estimate};
pub use settings::{LocateMethod, LocateSettings, Progress, Stage};
pub use stats::{Estimate, ListStats, OpCount};
pub use tables::ListTables;
