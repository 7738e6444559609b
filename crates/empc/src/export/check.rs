//! Checks of loaded or generated tables: every index inside its table,
//! children after their parent, the shapes.

use crate::error::EmpcError;
use crate::eval::{NO_ROW, NO_ROW8, TreeIndex};
use crate::tree::{CompactTables, OwnedTables};
use kestrel_core::Scalar;
use kestrel_core::formats::FormatError;

/// Checks that every index of the compact tables points inside its table
/// (roots, node rows and children, output bounds), that children come
/// after their parent (no cycles), and the table shapes.
pub(super) fn check_compact_tables<S: Scalar>(t: &CompactTables<S>) -> Result<(), EmpcError> {
    let w = t.n_params + 1;
    let bad = |what: String| Err(FormatError::invalid("compact_tables", what).into());
    if !t.rows.len().is_multiple_of(w) || !t.hull.len().is_multiple_of(w) {
        return bad(format!("rows and hull must hold {w} numbers per row"));
    }
    if t.theta_lb.len() != t.n_params || t.theta_ub.len() != t.n_params {
        return bad(format!("expected {} parameter bounds", t.n_params));
    }
    if t.roots.len() != t.n_outputs || t.bounds.len() != t.n_outputs {
        return bad(format!(
            "expected one root and one bound pair per output ({})",
            t.n_outputs
        ));
    }
    let nr = t.rows.len() / w;
    let row16 = |v: u8| if v == NO_ROW8 { NO_ROW } else { u16::from(v) };
    let nodes = t.nodes.iter().map(|n| {
        [
            row16(n.rows[0]),
            row16(n.rows[1]),
            n.children[0],
            n.children[1],
        ]
    });
    check_tree(TreeShape {
        what: "compact_tables",
        roots: &t.roots,
        nodes,
        n_nodes: t.nodes.len(),
        n_leaves: nr,
        n_rows: nr,
        bounds: &t.bounds,
        bounds_ok: t.theta_lb.iter().zip(&t.theta_ub).all(|(l, u)| l <= u),
    })
}

/// What [`check_tree`] checks of either layout.
struct TreeShape<'a, I, X> {
    what: &'static str,
    roots: &'a [X],
    /// `[row a, row b (NO_ROW: none), child, child]`.
    nodes: I,
    n_nodes: usize,
    /// Leaf payloads must be below this (laws, or rows in the compact layout).
    n_leaves: usize,
    n_rows: usize,
    bounds: &'a [[X; 2]],
    /// `theta_lb <= theta_ub`.
    bounds_ok: bool,
}

/// Every root, node row, child and output bound inside its table, children
/// after their parent (no cycles), the parameter box not empty.
fn check_tree<X: TreeIndex, I: Iterator<Item = [X; 4]>>(
    t: TreeShape<'_, I, X>,
) -> Result<(), EmpcError> {
    let (nr, nn, nl) = (t.n_rows, t.n_nodes, t.n_leaves);
    let bad = |what: String| Err(FormatError::invalid(t.what, what).into());
    let child_ok = |c: X| {
        if c.is_leaf() {
            c.payload().index() < nl
        } else {
            c.index() < nn
        }
    };
    if let Some(r) = t.roots.iter().find(|&&r| !child_ok(r)) {
        return bad(format!("root {r:?} points outside the tables"));
    }
    for (i, n) in t.nodes.enumerate() {
        let row_ok = |r: X| r.index() < nr;
        if !row_ok(n[0])
            || !(n[1] == X::NO_ROW || row_ok(n[1]))
            || !child_ok(n[2])
            || !child_ok(n[3])
        {
            return bad(format!("node {i} {n:?} points outside the tables"));
        }
        // Children come after their parent: no cycles.
        for c in [n[2], n[3]] {
            if !c.is_leaf() && c.index() <= i {
                return bad(format!("node {i} has a child {c:?} that is not after it"));
            }
        }
    }
    for b in t.bounds {
        for &r in b {
            if r != X::NO_ROW && r.index() >= nr {
                return bad(format!("an output bound uses row {r:?} of {nr}"));
            }
        }
    }
    if !t.bounds_ok {
        return bad("theta_lb exceeds theta_ub".into());
    }
    Ok(())
}

/// Checks that every index of the tables (either index type) points
/// inside its table.
pub(super) fn check_tables<S: Scalar, X: TreeIndex>(
    t: &OwnedTables<S, X>,
) -> Result<(), EmpcError> {
    let nr = t.rows.len() / (t.n_params + 1);
    if let Some(l) = t.laws.iter().find(|&&r| r.index() >= nr) {
        let l = l.index();
        return Err(FormatError::invalid("tables", format!("a law uses row {l} of {nr}")).into());
    }
    check_tree(TreeShape {
        what: "tables",
        roots: &[t.root],
        nodes: t.nodes.iter().copied(),
        n_nodes: t.nodes.len(),
        n_leaves: t.laws.len() / t.n_outputs.max(1),
        n_rows: nr,
        bounds: &t.bounds,
        bounds_ok: t.theta_lb.iter().zip(&t.theta_ub).all(|(l, u)| l <= u),
    })
}
