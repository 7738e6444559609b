//! Read access to the tables ([`TreeTables`]) and the tables in slices:
//! [`SliceTables`] (one tree, `u16` or `u32` indices) and [`ForestTables`]
//! (the compact layout, one tree per output).

use crate::eval::index::{NO_ROW, TreeIndex};
use kestrel_core::Scalar;

/// Read access to the tables of an explicit controller.
///
/// Every accessor returns `None` for an index outside its table, which the
/// evaluation turns into [`Error::OutOfRange`](kestrel_core::Error::OutOfRange) (corrupted tables), never a panic.
///
/// `I` is the index type: `u16` (the default) or `u32` (the wide layout,
/// [`WideSliceTables`]; its codes use [`WIDE_LEAF`](crate::eval::WIDE_LEAF) and [`WIDE_NO_ROW`](crate::eval::WIDE_NO_ROW)).
pub trait TreeTables<S: Scalar, I: TreeIndex = u16> {
    /// Number of parameters `p`.
    fn n_params(&self) -> usize;
    /// Number of outputs `k`.
    fn n_outputs(&self) -> usize;
    /// Number of tree nodes.
    fn n_nodes(&self) -> usize;
    /// The root as a child code (a node index, or a leaf).
    fn root(&self) -> I;
    /// Node `i`: `[row a, row b, child if a(theta) <= b(theta), child otherwise]`.
    fn node(&self, i: usize) -> Option<[I; 4]>;
    /// The affine row of output `out` under law `law`.
    fn law(&self, law: usize, out: usize) -> Option<I>;
    /// Entry `j` of affine row `r`: gain for `j < p`, constant for `j == p`.
    fn row(&self, r: usize, j: usize) -> Option<S>;
    /// The whole affine row `r` (`p + 1` entries) when the tables are in
    /// addressable memory: the evaluation then reads it as a slice, with
    /// the same arithmetic in the same order as through [`TreeTables::row`]
    /// (bit-identical results). `None` (the default, e.g. tables served
    /// from program memory): entry by entry through [`TreeTables::row`].
    fn row_slice(&self, r: usize) -> Option<&[S]> {
        let _ = r;
        None
    }
    /// Number of rows of the explored set.
    fn n_hull(&self) -> usize;
    /// Entry `j` of row `i` of the explored set (`a` then `b`).
    fn hull(&self, i: usize, j: usize) -> Option<S>;
    /// Lower and upper bound of parameter `j`.
    fn theta_bounds(&self, j: usize) -> Option<(S, S)>;
    /// Affine rows of the lower and upper bound of output `out` ([`NO_ROW`]: none).
    fn output_bounds(&self, out: usize) -> Option<[I; 2]>;
    /// The compact layout (one tree per output): the root child code of
    /// output `out`'s tree, whose leaves hold a law index of that output
    /// alone (read through [`TreeTables::law`] with the same `out`).
    /// `None` (the default): one tree for all outputs, rooted at
    /// [`TreeTables::root`].
    fn output_root(&self, out: usize) -> Option<I> {
        let _ = out;
        None
    }
}

/// "No row" in a [`CompactNode`].
pub const NO_ROW8: u8 = 0xFF;

/// A node of the compact layout, 6 bytes: rows `a`, `b` as `u8` (at most
/// 255 affine rows; [`NO_ROW8`] for `b` = 0) and the two child codes
/// (`a(theta) <= b(theta)` first), as in [`TreeTables::node`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompactNode {
    /// Rows `a` and `b`.
    pub rows: [u8; 2],
    /// Child codes: if `a(theta) <= b(theta)`, otherwise.
    pub children: [u16; 2],
}

/// The accessors [`ForestTables`] and [`SliceTables`] (either index type)
/// implement alike (same field names).
macro_rules! shared_accessors {
    ($i:ty) => {
        fn n_params(&self) -> usize {
            self.n_params
        }
        fn n_outputs(&self) -> usize {
            self.n_outputs
        }
        fn n_nodes(&self) -> usize {
            self.nodes.len()
        }
        fn row(&self, r: usize, j: usize) -> Option<S> {
            entry(self.rows, self.n_params + 1, r, j)
        }
        fn row_slice(&self, r: usize) -> Option<&[S]> {
            let w = self.n_params + 1;
            let start = r.checked_mul(w)?;
            self.rows.get(start..start.checked_add(w)?)
        }
        fn n_hull(&self) -> usize {
            self.hull.len() / (self.n_params + 1)
        }
        fn hull(&self, i: usize, j: usize) -> Option<S> {
            entry(self.hull, self.n_params + 1, i, j)
        }
        fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
            Some((*self.theta_lb.get(j)?, *self.theta_ub.get(j)?))
        }
        fn output_bounds(&self, out: usize) -> Option<[$i; 2]> {
            self.bounds.get(out).copied()
        }
    };
}

/// A node index no table reaches (tables have fewer nodes): a missing root.
const MISSING_NODE: u16 = 0x7FFF;

/// Compact tables (one tree per output, see [`TreeTables::output_root`]):
/// a leaf's payload is directly the affine row of its output's law, so
/// there is no law table.
#[derive(Clone, Copy, Debug)]
pub struct ForestTables<'a, S> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code of every output's tree.
    pub roots: &'a [u16],
    /// Tree nodes of all trees.
    pub nodes: &'a [CompactNode],
    /// Affine rows, `p + 1` entries each.
    pub rows: &'a [S],
    /// Explored set rows, `p + 1` entries each.
    pub hull: &'a [S],
    /// Parameter lower bounds.
    pub theta_lb: &'a [S],
    /// Parameter upper bounds.
    pub theta_ub: &'a [S],
    /// Per output: rows of the lower and upper bound.
    pub bounds: &'a [[u16; 2]],
}

impl<S: Scalar> TreeTables<S> for ForestTables<'_, S> {
    fn root(&self) -> u16 {
        self.roots.first().copied().unwrap_or(MISSING_NODE)
    }
    fn node(&self, i: usize) -> Option<[u16; 4]> {
        let n = self.nodes.get(i)?;
        let r = |v: u8| if v == NO_ROW8 { NO_ROW } else { u16::from(v) };
        Some([r(n.rows[0]), r(n.rows[1]), n.children[0], n.children[1]])
    }
    fn law(&self, law: usize, out: usize) -> Option<u16> {
        // The leaf payload is the row itself.
        (out < self.n_outputs && law < self.rows.len() / (self.n_params + 1)).then_some(law as u16)
    }
    shared_accessors!(u16);
    fn output_root(&self, out: usize) -> Option<u16> {
        // Out of range: a corrupted table, reported by the evaluation.
        Some(self.roots.get(out).copied().unwrap_or(MISSING_NODE))
    }
}

/// Tables in slices (RAM or `static` arrays): what the exported source builds.
///
/// `I` is the index type: `u16` (the default, [`LEAF`](crate::eval::LEAF), [`NO_ROW`]) or
/// `u32` ([`WideSliceTables`]).
#[derive(Clone, Copy, Debug)]
pub struct SliceTables<'a, S, I = u16> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code.
    pub root: I,
    /// Tree nodes.
    pub nodes: &'a [[I; 4]],
    /// Laws, `k` row indices each.
    pub laws: &'a [I],
    /// Affine rows, `p + 1` entries each.
    pub rows: &'a [S],
    /// Explored set rows, `p + 1` entries each.
    pub hull: &'a [S],
    /// Parameter lower bounds.
    pub theta_lb: &'a [S],
    /// Parameter upper bounds.
    pub theta_ub: &'a [S],
    /// Per output: rows of the lower and upper bound (`I::NO_ROW`: none).
    pub bounds: &'a [[I; 2]],
}

impl<S: Scalar, I: TreeIndex> TreeTables<S, I> for SliceTables<'_, S, I> {
    fn root(&self) -> I {
        self.root
    }
    fn node(&self, i: usize) -> Option<[I; 4]> {
        self.nodes.get(i).copied()
    }
    fn law(&self, law: usize, out: usize) -> Option<I> {
        if out >= self.n_outputs {
            return None;
        }
        self.laws
            .get(law.checked_mul(self.n_outputs)?.checked_add(out)?)
            .copied()
    }
    shared_accessors!(I);
}

/// Wide tables in slices (`u32` indices, [`WIDE_LEAF`](crate::eval::WIDE_LEAF) child codes,
/// [`WIDE_NO_ROW`](crate::eval::WIDE_NO_ROW)): the layout of trees beyond the 32767 nodes the `u16`
/// codes address, otherwise as [`SliceTables`] (the same struct with index
/// type `u32`). Evaluated by the same [`evaluate`](fn@crate::eval::evaluate).
///
/// ```
/// use kestrel_empc::evaluate;
/// use kestrel_empc::eval::{WideSliceTables, WIDE_LEAF, WIDE_NO_ROW};
/// // z = -theta for theta <= 0, z = 0 otherwise.
/// static T: WideSliceTables<'static, f64> = WideSliceTables {
///     n_params: 1, n_outputs: 1, root: 0,
///     nodes: &[[2, WIDE_NO_ROW, WIDE_LEAF, WIDE_LEAF | 1]],
///     laws: &[0, 1],
///     rows: &[-1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
///     hull: &[], theta_lb: &[-1.0], theta_ub: &[1.0],
///     bounds: &[[WIDE_NO_ROW, WIDE_NO_ROW]],
/// };
/// let mut z = [0.0];
/// let e = evaluate(&T, &[-0.5], &mut z).unwrap();
/// assert_eq!((z[0], e.law, e.outside), (0.5, 0_u32, false));
/// ```
pub type WideSliceTables<'a, S> = SliceTables<'a, S, u32>;

#[inline]
fn entry<S: Copy>(t: &[S], width: usize, i: usize, j: usize) -> Option<S> {
    if j >= width {
        return None;
    }
    t.get(i.checked_mul(width)?.checked_add(j)?).copied()
}
