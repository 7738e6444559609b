//! Point location and evaluation ([`evaluate`], [`evaluate_with`]).

use crate::eval::index::TreeIndex;
use crate::eval::tables::TreeTables;
use kestrel_core::{Error, Scalar};

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

/// What the evaluation reads besides the point location: affine rows,
/// laws, the explored set, the parameter box and the output bounds. Every
/// [`TreeTables`] has it; the candidate-list tables (`ListSlices`) too.
pub(super) trait Common<S: Scalar, I: TreeIndex> {
    fn n_params(&self) -> usize;
    fn n_outputs(&self) -> usize;
    fn law(&self, law: usize, out: usize) -> Option<I>;
    fn row(&self, r: usize, j: usize) -> Option<S>;
    fn row_slice(&self, r: usize) -> Option<&[S]>;
    fn n_hull(&self) -> usize;
    fn hull(&self, i: usize, j: usize) -> Option<S>;
    fn theta_bounds(&self, j: usize) -> Option<(S, S)>;
    fn output_bounds(&self, out: usize) -> Option<[I; 2]>;
}

/// [`TreeTables`] seen through [`Common`].
struct ViaTree<'t, T: ?Sized>(&'t T);

impl<S: Scalar, I: TreeIndex, T: TreeTables<S, I> + ?Sized> Common<S, I> for ViaTree<'_, T> {
    fn n_params(&self) -> usize {
        TreeTables::n_params(self.0)
    }
    fn n_outputs(&self) -> usize {
        TreeTables::n_outputs(self.0)
    }
    fn law(&self, law: usize, out: usize) -> Option<I> {
        TreeTables::law(self.0, law, out)
    }
    fn row(&self, r: usize, j: usize) -> Option<S> {
        TreeTables::row(self.0, r, j)
    }
    fn row_slice(&self, r: usize) -> Option<&[S]> {
        TreeTables::row_slice(self.0, r)
    }
    fn n_hull(&self) -> usize {
        TreeTables::n_hull(self.0)
    }
    fn hull(&self, i: usize, j: usize) -> Option<S> {
        TreeTables::hull(self.0, i, j)
    }
    fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
        TreeTables::theta_bounds(self.0, j)
    }
    fn output_bounds(&self, out: usize) -> Option<[I; 2]> {
        TreeTables::output_bounds(self.0, out)
    }
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
pub(super) fn row_at<S: Scalar, I: TreeIndex, T: Common<S, I> + ?Sized>(
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
    let (th, outside) = project(&ViaTree(tables), theta, scratch, z.len())?;
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
        *zo = output(&ViaTree(tables), th, l, o)?;
    }
    Ok(Evaluation {
        law,
        outside,
        steps,
    })
}

/// The checks and the projection every evaluation starts with: the
/// dimensions (`n_z` outputs), a finite `theta`, `theta` clamped to the
/// parameter box into `scratch`, and whether it lies outside the explored
/// set (outside the box or the hull).
pub(super) fn project<'s, S: Scalar, I: TreeIndex, T: Common<S, I> + ?Sized>(
    tables: &T,
    theta: &[S],
    scratch: &'s mut [S],
    n_z: usize,
) -> Result<(&'s [S], bool), Error> {
    let p = tables.n_params();
    if theta.len() != p {
        return Err(Error::DimensionMismatch {
            expected: p,
            found: theta.len(),
        });
    }
    if n_z != tables.n_outputs() {
        return Err(Error::DimensionMismatch {
            expected: tables.n_outputs(),
            found: n_z,
        });
    }
    let n_scratch = scratch.len();
    let Some(th) = scratch.get_mut(..p) else {
        return Err(Error::DimensionMismatch {
            expected: p,
            found: n_scratch,
        });
    };
    if !theta.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite);
    }
    th.copy_from_slice(theta);
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
    Ok((th, outside))
}

/// Output `o` of law `l` at `th`, clamped to the output's bounds.
pub(super) fn output<S: Scalar, I: TreeIndex, T: Common<S, I> + ?Sized>(
    tables: &T,
    th: &[S],
    l: I,
    o: usize,
) -> Result<S, Error> {
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
    Ok(v)
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
        let a = row_at(&ViaTree(tables), th, node[0].index())?;
        let b = if node[1] == I::NO_ROW {
            S::ZERO
        } else {
            row_at(&ViaTree(tables), th, node[1].index())?
        };
        code = if a <= b { node[2] } else { node[3] };
        steps = steps.saturating_add(1);
    }
    Ok((code.payload(), u16::try_from(steps).unwrap_or(u16::MAX)))
}
