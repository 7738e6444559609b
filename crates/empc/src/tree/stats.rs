//! What a tree construction reports.

/// Size and shape of the tree and tables.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeStats {
    /// Regions of the solution.
    pub regions: usize,
    /// Distinct laws (on the kept outputs).
    pub distinct_laws: usize,
    /// Distinct affine rows shared by the laws and bounds.
    pub distinct_rows: usize,
    /// Largest number of nodes on a root-to-leaf path.
    pub depth: usize,
    /// Tree nodes.
    pub nodes: usize,
    /// Distinct hyperplanes used by the nodes (each stored as a pair of
    /// affine rows; only those that are no difference of law and bound
    /// rows add a row).
    pub hyperplanes: usize,
    /// Leaves where the construction could not separate different laws
    /// (numerically degenerate cases); 0 in an exact tree.
    pub ambiguous_leaves: usize,
    /// Seconds spent building.
    pub build_seconds: f64,
}
