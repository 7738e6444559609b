//! What the point-location build reports, and the estimate before it.

/// Arithmetic operations of one evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpCount {
    /// Multiply-adds (one per gain of an affine row evaluated).
    pub mul_adds: usize,
    /// Comparisons (hyperplane sides, box and hull tests, output clamps).
    pub comparisons: usize,
}

/// Size and shape of candidate-list tables ([`build_lists`](crate::locate::build_lists)).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ListStats {
    /// Regions of the solution.
    pub regions: usize,
    /// Distinct laws (on the kept outputs).
    pub distinct_laws: usize,
    /// Affine rows stored (law rows, bound rows and explicit hyperplanes).
    pub distinct_rows: usize,
    /// Hyperplanes (facets and splits).
    pub hyperplanes: usize,
    /// Of those, how many need a row of their own (the others are the
    /// difference of two law rows).
    pub explicit_hyperplanes: usize,
    /// Facet references of all regions.
    pub facets: usize,
    /// Tree nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Region references in the leaves' lists.
    pub entries: usize,
    /// Largest number of nodes on a root-to-leaf path.
    pub depth: usize,
    /// Longest list of a leaf.
    pub max_leaf_regions: usize,
    /// Most operations an evaluation can take (path, region tests of the
    /// worst leaf, box and hull tests, outputs and their clamps).
    pub worst_case: OpCount,
    /// Most hyperplanes an evaluation can evaluate (path and region tests).
    pub worst_case_hyperplanes: usize,
    /// LPs solved while building.
    pub lps: usize,
    /// Storage in bytes: `f32` numbers, `u16` indices when every index
    /// fits (`u32` otherwise).
    pub bytes_f32: usize,
    /// Storage in bytes with `f64` numbers.
    pub bytes_f64: usize,
    /// Whether every index fits `u16` (the flash layout of the AVR).
    pub fits_u16: bool,
    /// Seconds spent building.
    pub build_seconds: f64,
}

/// A cheap estimate of the point location before building it
/// ([`estimate`](crate::locate::estimate)): the shared tables are counted
/// exactly (law rows, hyperplanes, facets), the tree from rules of thumb.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The structure [`LocateMethod::Auto`](crate::locate::LocateMethod::Auto) (or the settings) would build.
    pub method: crate::locate::LocateMethod,
    /// Regions of the solution.
    pub regions: usize,
    /// Distinct laws on the kept outputs.
    pub distinct_laws: usize,
    /// Estimated tree nodes.
    pub nodes: usize,
    /// Estimated storage in bytes (`f32` numbers, `u16` indices when they fit).
    pub bytes_f32: usize,
    /// Estimated build time in seconds on one core (order of magnitude).
    pub seconds: f64,
}
