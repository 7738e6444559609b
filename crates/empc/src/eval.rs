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

use kestrel_core::{Error, Scalar};

/// Marks a child code as a leaf; the low 15 bits are then the law index.
pub const LEAF: u16 = 0x8000;
/// "No row" in the output-bound table.
pub const NO_ROW: u16 = 0xFFFF;

/// Marks a child code of the wide layout (index type `u32`) as a leaf;
/// the low 31 bits are then the law index.
pub const WIDE_LEAF: u32 = 0x8000_0000;
/// "No row" in the wide layout.
pub const WIDE_NO_ROW: u32 = u32::MAX;

/// The index type of a table layout: `u16` (the default, flash-ready: at
/// most 32767 nodes and laws, 65534 rows) or `u32` (the wide layout for
/// trees beyond the `u16` codes, with [`WIDE_LEAF`] and [`WIDE_NO_ROW`]).
pub trait TreeIndex: Copy + Eq + core::fmt::Debug {
    /// The leaf bit of a child code.
    const LEAF: Self;
    /// "No row".
    const NO_ROW: Self;
    /// The value as an index.
    fn index(self) -> usize;
    /// Whether the child code is a leaf.
    fn is_leaf(self) -> bool;
    /// The child code without its leaf bit.
    fn payload(self) -> Self;
}

impl TreeIndex for u16 {
    const LEAF: u16 = LEAF;
    const NO_ROW: u16 = NO_ROW;
    #[inline]
    fn index(self) -> usize {
        self as usize
    }
    #[inline]
    fn is_leaf(self) -> bool {
        self & LEAF != 0
    }
    #[inline]
    fn payload(self) -> u16 {
        self & !LEAF
    }
}

impl TreeIndex for u32 {
    const LEAF: u32 = WIDE_LEAF;
    const NO_ROW: u32 = WIDE_NO_ROW;
    /// On a 16-bit target an index beyond `usize` becomes `usize::MAX`,
    /// which no table holds: the accessors return `None`, never a
    /// truncated index.
    #[inline]
    fn index(self) -> usize {
        usize::try_from(self).unwrap_or(usize::MAX)
    }
    #[inline]
    fn is_leaf(self) -> bool {
        self & WIDE_LEAF != 0
    }
    #[inline]
    fn payload(self) -> u32 {
        self & !WIDE_LEAF
    }
}

/// Read access to the tables of an explicit controller.
///
/// Every accessor returns `None` for an index outside its table, which the
/// evaluation turns into [`Error::OutOfRange`] (corrupted tables), never a panic.
///
/// `I` is the index type: `u16` (the default) or `u32` (the wide layout,
/// [`WideSliceTables`]; its codes use [`WIDE_LEAF`] and [`WIDE_NO_ROW`]).
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
/// `I` is the index type: `u16` (the default, [`LEAF`], [`NO_ROW`]) or
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

/// Wide tables in slices (`u32` indices, [`WIDE_LEAF`] child codes,
/// [`WIDE_NO_ROW`]): the layout of trees beyond the 32767 nodes the `u16`
/// codes address, otherwise as [`SliceTables`] (the same struct with index
/// type `u32`). Evaluated by the same [`evaluate`].
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

/// What the evaluation found (`I`: the tables' index type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Evaluation<I = u16> {
    /// The law used.
    pub law: I,
    /// `theta` was outside the explored set (outside the box or the hull):
    /// the output is the clamped law of the nearest region (see the module doc).
    pub outside: bool,
    /// Tree nodes visited.
    pub steps: u16,
}

/// `row' [theta; 1]` for an affine row read through `get`.
#[inline]
fn affine<S: Scalar>(theta: &[S], get: impl Fn(usize) -> Option<S>) -> Result<S, Error> {
    let p = theta.len();
    let mut acc = get(p).ok_or(Error::OutOfRange)?;
    for (j, t) in theta.iter().enumerate() {
        acc = acc.mul_add(get(j).ok_or(Error::OutOfRange)?, *t);
    }
    Ok(acc)
}

/// Affine row `r` of the tables at `th` (`p` entries): through
/// [`TreeTables::row_slice`] when the tables give it, else entry by entry;
/// the same operations in the same order either way.
#[inline]
fn row_at<S: Scalar, I: TreeIndex, T: TreeTables<S, I> + ?Sized>(
    tables: &T,
    th: &[S],
    r: usize,
) -> Result<S, Error> {
    match tables.row_slice(r) {
        Some(row) => {
            let p = th.len();
            let (Some(gains), Some(&c)) = (row.get(..p), row.get(p)) else {
                return Err(Error::OutOfRange);
            };
            let mut acc = c;
            for (g, t) in gains.iter().zip(th) {
                acc = acc.mul_add(*g, *t);
            }
            Ok(acc)
        }
        None => affine(th, |j| tables.row(r, j)),
    }
}

/// Locates `theta` in the tree and writes the law's outputs into `z`.
///
/// `P` is the number of parameters (it must match the tables); `z` must have
/// the tables' number of outputs. Errors: a dimension mismatch, a
/// non-finite `theta`, or corrupted tables ([`Error::OutOfRange`]).
///
/// ```
/// use kestrel_empc::{evaluate, SliceTables, LEAF, NO_ROW};
/// // One parameter, one output: z = -theta for theta <= 0, z = 0 otherwise.
/// static T: SliceTables<'static, f64> = SliceTables {
///     n_params: 1, n_outputs: 1, root: 0,
///     nodes: &[[2, NO_ROW, LEAF, LEAF | 1]], // theta <= 0 goes to law 0
///     laws: &[0, 1],
///     rows: &[-1.0, 0.0, 0.0, 0.0, 1.0, 0.0], // -theta, 0, theta
///     hull: &[], theta_lb: &[-1.0], theta_ub: &[1.0],
///     bounds: &[[NO_ROW, NO_ROW]],
/// };
/// let mut z = [0.0];
/// let e = evaluate(&T, &[-0.5], &mut z).unwrap();
/// assert_eq!((z[0], e.law, e.outside), (0.5, 0, false));
/// let e = evaluate(&T, &[3.0], &mut z).unwrap(); // outside: clamped to the box
/// assert_eq!((z[0], e.law, e.outside), (0.0, 1, true));
/// ```
pub fn evaluate<S: Scalar, I: TreeIndex, T: TreeTables<S, I> + ?Sized, const P: usize>(
    tables: &T,
    theta: &[S; P],
    z: &mut [S],
) -> Result<Evaluation<I>, Error> {
    let mut scratch = [S::ZERO; P];
    evaluate_with(tables, theta, &mut scratch, z)
}

/// [`evaluate`] for a parameter count known only at run time: `scratch`
/// (at least `p` entries, caller-owned) holds the projected parameter.
pub fn evaluate_with<S: Scalar, I: TreeIndex, T: TreeTables<S, I> + ?Sized>(
    tables: &T,
    theta: &[S],
    scratch: &mut [S],
    z: &mut [S],
) -> Result<Evaluation<I>, Error> {
    let p = tables.n_params();
    if theta.len() != p {
        return Err(Error::DimensionMismatch {
            expected: p,
            found: theta.len(),
        });
    }
    if z.len() != tables.n_outputs() {
        return Err(Error::DimensionMismatch {
            expected: tables.n_outputs(),
            found: z.len(),
        });
    }
    let Some(th) = scratch.get_mut(..p) else {
        return Err(Error::DimensionMismatch {
            expected: p,
            found: scratch.len(),
        });
    };
    if !theta.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite);
    }
    th.copy_from_slice(theta);
    let th: &mut [S] = th;
    let mut outside = false;
    for (j, v) in th.iter_mut().enumerate() {
        let (lo, hi) = tables.theta_bounds(j).ok_or(Error::OutOfRange)?;
        if *v < lo || *v > hi {
            outside = true;
            *v = v.clamp(lo, hi);
        }
    }
    let th: &[S] = th;
    #[allow(non_snake_case)]
    let P = p;
    if !outside {
        for i in 0..tables.n_hull() {
            // a'theta - b > 0 means outside.
            let b = tables.hull(i, P).ok_or(Error::OutOfRange)?;
            let s = affine(th, |j| {
                if j == P {
                    Some(S::ZERO)
                } else {
                    tables.hull(i, j)
                }
            })?;
            if s > b {
                outside = true;
                break;
            }
        }
    }
    // One shared tree, or (compact layout) one tree per output.
    let shared = tables.output_root(0).is_none();
    let (mut law, mut steps) = if shared {
        locate(tables, th, tables.root())?
    } else {
        (I::LEAF.payload(), 0) // law 0 until output 0's tree gives it
    };
    for (o, zo) in z.iter_mut().enumerate() {
        let l = if shared {
            law
        } else {
            let root = tables.output_root(o).ok_or(Error::OutOfRange)?;
            let (l, s) = locate(tables, th, root)?;
            steps = steps.saturating_add(s);
            if o == 0 {
                law = l;
            }
            l
        };
        let r = tables.law(l.index(), o).ok_or(Error::OutOfRange)?.index();
        let mut v = row_at(tables, th, r)?;
        let [lo, hi] = tables.output_bounds(o).ok_or(Error::OutOfRange)?;
        if lo != I::NO_ROW {
            let l = row_at(tables, th, lo.index())?;
            v = v.max(l);
        }
        if hi != I::NO_ROW {
            let u = row_at(tables, th, hi.index())?;
            v = v.min(u);
        }
        *zo = v;
    }
    Ok(Evaluation {
        law,
        outside,
        steps,
    })
}

/// Walks the tree from the child code `code` to a leaf: its payload and
/// the nodes visited.
fn locate<S: Scalar, I: TreeIndex, T: TreeTables<S, I> + ?Sized>(
    tables: &T,
    th: &[S],
    mut code: I,
) -> Result<(I, u16), Error> {
    // A path visits each node at most once: more steps than nodes is a cycle.
    let mut steps: usize = 0;
    let limit = tables.n_nodes();
    while !code.is_leaf() {
        if steps > limit {
            return Err(Error::OutOfRange); // a cycle: corrupted tables
        }
        let node = tables.node(code.index()).ok_or(Error::OutOfRange)?;
        let a = row_at(tables, th, node[0].index())?;
        let b = if node[1] == I::NO_ROW {
            S::ZERO
        } else {
            row_at(tables, th, node[1].index())?
        };
        code = if a <= b { node[2] } else { node[3] };
        steps = steps.saturating_add(1);
    }
    Ok((code.payload(), u16::try_from(steps).unwrap_or(u16::MAX)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_core::Q16;

    // Node: row 3 (theta0) <= 0 -> law 0.
    static NODES: [[u16; 4]; 1] = [[3, NO_ROW, LEAF, LEAF | 1]];
    fn tables<S: Scalar>(buf: &mut [S; 12]) -> SliceTables<'_, S> {
        // rows: [-1, 0 | 0], [0, 0 | 0.25], [0, 0 | -1], [1, 0 | 0]
        let v = [
            -1.0, 0.0, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0,
        ];
        for (d, s) in buf.iter_mut().zip(v) {
            *d = S::from_f64(s);
        }
        let rows = &buf[..];
        SliceTables {
            n_params: 2,
            n_outputs: 1,
            root: 0,
            nodes: &NODES,
            laws: &[0, 1],
            rows,
            hull: &[],
            theta_lb: &[],
            theta_ub: &[],
            bounds: &[[NO_ROW, NO_ROW]],
        }
    }

    #[test]
    fn errors_not_panics() {
        let mut buf = [0.0f64; 12];
        let t = tables(&mut buf);
        let mut z = [0.0];
        // theta bounds table is empty: corrupted -> OutOfRange.
        assert_eq!(evaluate(&t, &[0.0, 0.0], &mut z), Err(Error::OutOfRange));
        let lb = [-1.0, -1.0];
        let ub = [1.0, 1.0];
        let t = SliceTables {
            theta_lb: &lb,
            theta_ub: &ub,
            ..t
        };
        assert_eq!(
            evaluate(&t, &[f64::NAN, 0.0], &mut z),
            Err(Error::NonFinite)
        );
        assert_eq!(
            evaluate(&t, &[0.0, 0.0, 0.0], &mut z),
            Err(Error::DimensionMismatch {
                expected: 2,
                found: 3
            })
        );
        let mut z2 = [0.0; 2];
        assert!(matches!(
            evaluate(&t, &[0.0, 0.0], &mut z2),
            Err(Error::DimensionMismatch { .. })
        ));
        let e = evaluate(&t, &[-0.5, 0.0], &mut z).unwrap();
        assert_eq!((e.law, z[0]), (0, 0.5));
        let e = evaluate(&t, &[0.5, 0.0], &mut z).unwrap();
        assert_eq!((e.law, z[0]), (1, 0.25));
        // A cycle in the node table is detected.
        let cyc = [[3u16, NO_ROW, 0, 0]];
        let t2 = SliceTables { nodes: &cyc, ..t };
        assert_eq!(evaluate(&t2, &[0.5, 0.0], &mut z), Err(Error::OutOfRange));
        // A law pointing past the row table.
        let t3 = SliceTables { laws: &[0, 9], ..t };
        assert_eq!(evaluate(&t3, &[0.5, 0.0], &mut z), Err(Error::OutOfRange));
    }

    #[test]
    fn forest_tables_and_their_errors() {
        // Two outputs, one parameter: z0 = -theta for theta <= 0 else 0,
        // z1 = 0.25 everywhere (a lone leaf).
        let rows = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.25, 1.0, 0.0];
        let nodes = [CompactNode {
            rows: [3, NO_ROW8],
            children: [LEAF, LEAF | 1],
        }];
        let t = ForestTables {
            n_params: 1,
            n_outputs: 2,
            roots: &[0, LEAF | 2],
            nodes: &nodes,
            rows: &rows,
            hull: &[],
            theta_lb: &[-1.0],
            theta_ub: &[1.0],
            bounds: &[[NO_ROW, NO_ROW]; 2],
        };
        let mut z = [0.0; 2];
        let e = evaluate(&t, &[-0.5], &mut z).unwrap();
        assert_eq!((z, e.law, e.steps, e.outside), ([0.5, 0.25], 0, 1, false));
        let e = evaluate(&t, &[0.5], &mut z).unwrap();
        assert_eq!((z, e.law), ([0.0, 0.25], 1));
        // A missing root, a leaf past the rows, a cycle: errors, no panic.
        let t1 = ForestTables { roots: &[0], ..t };
        assert_eq!(evaluate(&t1, &[0.5], &mut z), Err(Error::OutOfRange));
        let t2 = ForestTables { roots: &[], ..t };
        assert_eq!(evaluate(&t2, &[0.5], &mut z), Err(Error::OutOfRange));
        let t3 = ForestTables {
            roots: &[0, LEAF | 9],
            ..t
        };
        assert_eq!(evaluate(&t3, &[0.5], &mut z), Err(Error::OutOfRange));
        let cyc = [CompactNode {
            rows: [3, NO_ROW8],
            children: [0, 0],
        }];
        let t4 = ForestTables { nodes: &cyc, ..t };
        assert_eq!(evaluate(&t4, &[0.5], &mut z), Err(Error::OutOfRange));
    }

    #[test]
    fn fixed_point_same_leaf() {
        let mut buf = [Q16::ZERO; 12];
        let t = tables(&mut buf);
        let lb = [Q16::from_f64(-1.0); 2];
        let ub = [Q16::from_f64(1.0); 2];
        let t = SliceTables {
            theta_lb: &lb,
            theta_ub: &ub,
            ..t
        };
        let mut z = [Q16::ZERO];
        let e = evaluate(&t, &[Q16::from_f64(-0.25), Q16::ZERO], &mut z).unwrap();
        assert_eq!(e.law, 0);
        assert_eq!(z[0].to_f64(), 0.25);
        let e = evaluate(&t, &[Q16::from_f64(-3.0), Q16::ZERO], &mut z).unwrap();
        assert!(e.outside);
        assert_eq!(z[0].to_f64(), 1.0);
    }
}
