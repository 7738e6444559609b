//! The settings of the point-location build and the progress it reports.

use crate::error::EmpcError;
use crate::tree::{Outputs, TreeSettings};

/// Which point-location structure [`build_locator`](crate::locate::build_locator) builds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LocateMethod {
    /// The exact search tree ([`LocateMethod::Tree`]) for at most
    /// [`LocateSettings::auto_tree_regions`] regions, the candidate lists
    /// ([`LocateMethod::Lists`]) above.
    #[default]
    Auto,
    /// The binary search tree over the facets (Tøndel, Johansen and
    /// Bemporad 2003; [`crate::tree`]): leaves hold single laws, the
    /// fastest evaluation, but its size grows much faster than the regions.
    Tree,
    /// A shallow tree whose leaves list a few candidate regions, each
    /// tested by its facets: size and build time about linear in the
    /// regions ([`build_lists`](crate::locate::build_lists)).
    Lists,
}

/// Settings of the point-location build.
#[derive(Clone, Debug)]
pub struct LocateSettings {
    /// The structure to build.
    pub method: LocateMethod,
    /// The outputs to keep (as [`TreeSettings::outputs`]).
    pub outputs: Outputs,
    /// Two affine rows are the same law row if they differ by at most this
    /// (relative to their size), as [`TreeSettings::law_tol`].
    pub law_tol: f64,
    /// A leaf may list at most this many regions to test (regions of the
    /// leaf's final law are not tested); larger cells are split further.
    pub leaf_regions: usize,
    /// Most tree nodes on a path; a cell at this depth becomes a leaf
    /// whatever it holds.
    pub max_depth: usize,
    /// Candidate hyperplanes ranked per node without LPs (the most
    /// frequent facets of the node's regions).
    pub candidates: usize,
    /// Of those, how many are tried with LPs (the best split is taken).
    pub tries: usize,
    /// A cell is split only when each side keeps at most this fraction of
    /// its regions (in `(0, 1)`); otherwise it becomes a leaf with a
    /// longer list.
    pub shrink: f64,
    /// Split with LPs on several threads (needs the `parallel` feature;
    /// ignored otherwise). The structure is the same.
    pub parallel: bool,
    /// [`LocateMethod::Auto`] builds the exact tree up to this many regions.
    pub auto_tree_regions: usize,
    /// Settings of the exact tree ([`LocateMethod::Tree`]); its `outputs`
    /// and `law_tol` are replaced by the ones above.
    pub tree: TreeSettings,
}

impl Default for LocateSettings {
    fn default() -> Self {
        LocateSettings {
            method: LocateMethod::Auto,
            outputs: Outputs::All,
            law_tol: 1e-9,
            leaf_regions: 24,
            max_depth: 40,
            candidates: 24,
            tries: 4,
            shrink: 0.85,
            parallel: true,
            auto_tree_regions: 200,
            tree: TreeSettings::default(),
        }
    }
}

impl LocateSettings {
    /// Checks the settings: `law_tol` finite and positive, `leaf_regions`,
    /// `max_depth`, `candidates` and `tries` at least 1, `max_depth` at
    /// most 1000, `shrink` in `(0, 1)`.
    pub fn validate(&self) -> Result<(), EmpcError> {
        let bad = |what: &str| Err(EmpcError::InvalidArgument(what.into()));
        if !(self.law_tol.is_finite() && self.law_tol > 0.0) {
            return bad("LocateSettings::law_tol must be finite and positive");
        }
        if self.leaf_regions == 0 {
            return bad("LocateSettings::leaf_regions must be at least 1");
        }
        if self.max_depth == 0 || self.max_depth > 1000 {
            return bad("LocateSettings::max_depth must be in 1..=1000");
        }
        if self.candidates == 0 || self.tries == 0 {
            return bad("LocateSettings::candidates and tries must be at least 1");
        }
        if !(self.shrink > 0.0 && self.shrink < 1.0) {
            return bad("LocateSettings::shrink must be in (0, 1)");
        }
        if let Outputs::First(0) = self.outputs {
            return bad("LocateSettings::outputs: Outputs::First(k) needs k >= 1");
        }
        Ok(())
    }
}

/// A stage of the point-location build ([`Progress`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Sharing the laws' affine rows.
    Laws,
    /// Collecting the facet hyperplanes (`done` of `total` regions).
    Hyperplanes,
    /// Building the tree (`done` of `total` thousandths of the parameter
    /// space placed in leaves; [`LocateMethod::Tree`]: one report at the
    /// start and one at the end).
    Tree,
    /// Writing the tables.
    Tables,
}

/// A progress report of the point-location build (see [`Stage`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// The stage.
    pub stage: Stage,
    /// Work done in the stage.
    pub done: usize,
    /// Work of the whole stage.
    pub total: usize,
}
