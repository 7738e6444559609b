//! Complexity reduction and the binary search tree (design time).
//!
//! - Only the first `k` outputs of `z` are kept ([`Outputs`]); their affine
//!   rows are shared between laws and identical laws are stored once, so
//!   regions with the same law are merged in storage (the tree never
//!   distinguishes them: a leaf is reached as soon as one law is left).
//! - The tree follows Tøndel, Johansen and Bemporad (2003): the hyperplanes
//!   are the regions' facets; each node takes the candidate hyperplane that
//!   minimises the larger number of regions left on either side (then their
//!   sum), regions straddling it are kept on a side only if they meet that
//!   side of the node's cell in a full-dimensional set (an LP).
//!
//! One file per concept: `settings` and `stats`, the table types
//! (`tables`, `compact`), the entry points (`build`, `compact`),
//! the assembly of the tables from a solution (`assemble`), the search
//! itself (`search`) and the row sharing of the compact layout
//! (`share_rows`).

mod assemble;
mod build;
mod compact;
mod search;
mod settings;
mod share_rows;
mod stats;
mod tables;
#[cfg(test)]
mod tests;

pub(crate) use assemble::{SharedLaws, share_laws};
pub use build::{AnyController, ExplicitController, build_any, build_controller};
pub use compact::{CompactController, CompactTables, build_compact};
pub use settings::{
    AUTO_SAMPLED_REGIONS, DEFAULT_MAX_NODES, MAX_NODES, Outputs, TreeLayout, TreeMethod,
    TreeSettings, WIDE_MAX_NODES,
};
pub use stats::TreeStats;
pub use tables::{AnyTables, OwnedTables, WideTables};
