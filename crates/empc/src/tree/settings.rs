//! The settings of the reduction and the tree construction.

use crate::eval::{LEAF, WIDE_LEAF};

/// Which part of `z` the controller outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Outputs {
    /// All of `z`.
    #[default]
    All,
    /// The first `k` entries (the first move of a condensed MPC).
    First(usize),
}

/// Settings of the reduction and the tree construction.
#[derive(Clone, Debug)]
pub struct TreeSettings {
    /// The outputs to keep.
    pub outputs: Outputs,
    /// Two affine rows are the same law row if they differ by at most this
    /// (relative to their size).
    pub law_tol: f64,
    /// Candidate hyperplanes scored per node (the most frequent facets)
    /// when the node has too many regions for exact scoring.
    pub max_candidates: usize,
    /// A node scores every facet of its regions exactly (one LP per
    /// straddling region and side) when regions x facets is at most this.
    pub exact_budget: usize,
    /// Clipping: a leaf may hold one law for regions with other laws when,
    /// after the evaluation clamps the outputs to their bounds, it gives
    /// the same `z` on all of them (each differing output of a region is
    /// saturated there, and the leaf's law lies beyond that bound on the
    /// whole region; checked with one LP per output). Fewer leaves, the
    /// same answers.
    pub clipping: bool,
    /// How candidate hyperplanes are scored ([`TreeMethod::Auto`] by default).
    pub method: TreeMethod,
    /// Score candidates and split regions on several threads (needs the
    /// `parallel` feature; ignored otherwise). The tree is the same.
    pub parallel: bool,
    /// Stop with [`EmpcError::TooLarge`](crate::EmpcError::TooLarge) once the tree has this many nodes
    /// ([`TreeMethod::Sampled`]), instead of running on for hours. The
    /// default, [`DEFAULT_MAX_NODES`], allows wide trees; the `u16` layout
    /// ([`build_controller`](crate::tree::build_controller), [`TreeLayout::Narrow`]) stops at
    /// [`MAX_NODES`] whatever this says, the wide layout at
    /// [`WIDE_MAX_NODES`].
    pub max_nodes: usize,
    /// The table layout [`build_any`](crate::tree::build_any) returns ([`TreeLayout::Auto`]: `u16`
    /// when the tree fits, else `u32`). [`build_controller`](crate::tree::build_controller) always builds
    /// the `u16` layout.
    pub layout: TreeLayout,
}

/// The index width of the tables ([`build_any`](crate::tree::build_any)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TreeLayout {
    /// `u16` when the tree fits ([`MAX_NODES`] nodes, 65534 rows), else `u32`.
    #[default]
    Auto,
    /// Always `u16` ([`OwnedTables`](crate::tree::OwnedTables)): [`EmpcError::TooLarge`](crate::EmpcError::TooLarge) beyond
    /// [`MAX_NODES`] nodes.
    Narrow,
    /// Always `u32` ([`WideTables`](crate::tree::WideTables)), even when the tree would fit `u16`
    /// (the same tree, node for node).
    Wide,
}

/// How the tree construction scores candidate hyperplanes at a node.
///
/// Both are exact: a region is dropped from a side only when an LP (or its
/// own facet, or its bounding box) proves it does not meet that side of
/// the cell in a full-dimensional set. They differ in how the split is
/// chosen, which changes the tree's size and the build time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TreeMethod {
    /// [`TreeMethod::Lp`] up to [`AUTO_SAMPLED_REGIONS`] regions,
    /// [`TreeMethod::Sampled`] above.
    #[default]
    Auto,
    /// The best few candidates (after a ranking without LPs) are scored
    /// exactly: per straddling region and side an LP within the cell. Small
    /// trees, but slow beyond a few hundred regions.
    Lp,
    /// Candidates are scored without LPs, from sample points kept inside
    /// every region and cell (interior points found by the LPs along the
    /// way); only the chosen split runs LPs, at most one per region whose
    /// points lie on one side. Builds trees over thousands of regions in
    /// seconds (thesis problem with `Ns = 2`: 1545 regions).
    Sampled,
}

/// Above this many regions [`TreeMethod::Auto`] uses [`TreeMethod::Sampled`].
pub const AUTO_SAMPLED_REGIONS: usize = 400;

/// Most nodes the `u16` child codes address (the [`LEAF`] bit marks leaves).
pub const MAX_NODES: usize = LEAF as usize - 1;

/// Most nodes the wide layout's `u32` child codes address ([`WIDE_LEAF`]).
pub const WIDE_MAX_NODES: usize = WIDE_LEAF as usize - 1;

/// The default [`TreeSettings::max_nodes`]: room for the wide trees of
/// the Ns = 2 class problems (about 10^5 to 10^6 nodes) while a build
/// that runs away still stops in reasonable time.
pub const DEFAULT_MAX_NODES: usize = 2_000_000;

impl Default for TreeSettings {
    fn default() -> Self {
        TreeSettings {
            outputs: Outputs::All,
            law_tol: 1e-9,
            max_candidates: 40,
            exact_budget: 60_000,
            clipping: true,
            method: TreeMethod::Auto,
            parallel: true,
            max_nodes: DEFAULT_MAX_NODES,
            layout: TreeLayout::Auto,
        }
    }
}
