//! Point location by a shallow tree whose leaves hold short lists of
//! candidate regions ([`ListSlices`], [`evaluate_lists`]).
//!
//! The tree's nodes split by facet hyperplanes until a cell meets few
//! regions; a leaf lists the regions to test in turn (each by its own
//! facets, stored once as hyperplane indices) and ends with a final law,
//! the answer when no listed region contains `theta`: the regions meeting
//! the leaf's cell cover it, so inside the explored set the final law is
//! the one of the remaining regions. A hyperplane is two affine rows
//! `r1(theta) - r2(theta)`: a facet between regions with different laws is
//! where the two (continuous) laws meet, the difference of two stored law
//! rows, so most hyperplanes cost two indices and no numbers.
//!
//! The evaluation reads the tables through [`ListAccess`]: [`ListSlices`]
//! (RAM or `static` arrays) has it, and so can an accessor serving the
//! tables from program memory (kestrel-avr-rt's `locate::FlashLists`).

use crate::eval::evaluate::{Common, project, row_at};
use crate::eval::index::TreeIndex;
use kestrel_core::{Error, Scalar};

/// The candidate-list tables in slices (RAM or `static` arrays), index
/// type `I` (`u16` or `u32`). A child code, a hyperplane reference with
/// its side, and a row index use [`TreeIndex`]'s conventions: the
/// [`TreeIndex::LEAF`] bit marks a leaf in a child code and the other side
/// (`r1 >= r2`) in a facet; [`TreeIndex::NO_ROW`] is the zero row.
#[derive(Clone, Copy, Debug)]
pub struct ListSlices<'a, S, I = u16> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code (a node index, or `LEAF | leaf index`).
    pub root: I,
    /// Tree nodes `[hyperplane, child if r1 <= r2, child otherwise]`.
    pub nodes: &'a [[I; 3]],
    /// Leaves `[first entry, end entry, final law]`: the regions
    /// `entries[first..end]` are tested in turn.
    pub leaves: &'a [[I; 3]],
    /// The regions listed by the leaves.
    pub entries: &'a [I],
    /// Region `r`'s facets are `facets[region_start[r]..region_start[r + 1]]`
    /// (`regions + 1` entries).
    pub region_start: &'a [I],
    /// Facets: a hyperplane index, with the `LEAF` bit when the region lies
    /// on the side `r1 >= r2`.
    pub facets: &'a [I],
    /// The law of every region.
    pub region_law: &'a [I],
    /// Hyperplanes `[r1, r2]`: `r1(theta) - r2(theta)` (`r2 = NO_ROW`: zero).
    pub hyperplanes: &'a [[I; 2]],
    /// Laws, `k` row indices each.
    pub laws: &'a [I],
    /// Affine rows, `p + 1` entries each (gains, then the constant).
    pub rows: &'a [S],
    /// Explored set rows `a, b` (`a'theta <= b`), `p + 1` entries each.
    pub hull: &'a [S],
    /// Parameter lower bounds.
    pub theta_lb: &'a [S],
    /// Parameter upper bounds.
    pub theta_ub: &'a [S],
    /// Per output: rows of the lower and upper bound (`NO_ROW`: none).
    pub bounds: &'a [[I; 2]],
}

/// What [`evaluate_lists`] reads: the candidate-list tables entry by
/// entry, each read `None` when out of range (the evaluation then returns
/// [`Error::OutOfRange`]). [`ListSlices`] implements it over slices; an
/// accessor over program memory implements it with flash reads. The
/// conventions are [`ListSlices`]' (see its fields).
pub trait ListAccess<S: Scalar, I: TreeIndex> {
    /// Number of parameters `p`.
    fn n_params(&self) -> usize;
    /// Number of outputs `k`.
    fn n_outputs(&self) -> usize;
    /// The root child code.
    fn root(&self) -> I;
    /// Number of tree nodes.
    fn n_nodes(&self) -> usize;
    /// Node `i`: `[hyperplane, child if r1 <= r2, child otherwise]`.
    fn node(&self, i: usize) -> Option<[I; 3]>;
    /// Leaf `i`: `[first entry, end entry, final law]`.
    fn leaf(&self, i: usize) -> Option<[I; 3]>;
    /// List entry `i` (a region).
    fn entry(&self, i: usize) -> Option<I>;
    /// Where region `r`'s facets start (`r` up to the number of regions,
    /// where it is the end of the last region's).
    fn region_start(&self, r: usize) -> Option<I>;
    /// Facet reference `i` (hyperplane index, `LEAF` bit for the side
    /// `r1 >= r2`).
    fn facet(&self, i: usize) -> Option<I>;
    /// The law of region `r`.
    fn region_law(&self, r: usize) -> Option<I>;
    /// Hyperplane `h`: `[r1, r2]`.
    fn hyperplane(&self, h: usize) -> Option<[I; 2]>;
    /// Row index of output `out` of law `law`.
    fn law(&self, law: usize, out: usize) -> Option<I>;
    /// Entry `j` (`0..=p`) of affine row `r`.
    fn row(&self, r: usize, j: usize) -> Option<S>;
    /// Row `r` as a slice when the tables hold it in RAM (the same
    /// numbers as [`ListAccess::row`]); `None` (the default) makes the
    /// evaluation read entry by entry, in the same order.
    fn row_slice(&self, r: usize) -> Option<&[S]> {
        let _ = r;
        None
    }
    /// `row' [theta; 1]` for affine row `r` computed by the accessor in
    /// one pass (for tables in program memory: one address computation
    /// per row instead of one per entry), or `None` (the default) to read
    /// the row entry by entry. An implementation must do the evaluation's
    /// operations in its order: `acc = row[p]`, then `acc =
    /// acc.mul_add(row[j], theta[j])` for `j` in `0..p`, so that every
    /// accessor gives the same bits; `None` for a row out of range.
    fn row_value(&self, r: usize, theta: &[S]) -> Option<S> {
        let _ = (r, theta);
        None
    }
    /// Rows of the explored set.
    fn n_hull(&self) -> usize;
    /// Entry `j` (`0..=p`) of the explored set's row `i`.
    fn hull(&self, i: usize, j: usize) -> Option<S>;
    /// Lower and upper bound of parameter `j`.
    fn theta_bounds(&self, j: usize) -> Option<(S, S)>;
    /// Rows of output `out`'s lower and upper bound (`NO_ROW`: none).
    fn output_bounds(&self, out: usize) -> Option<[I; 2]>;
}

impl<S: Scalar, I: TreeIndex> ListAccess<S, I> for ListSlices<'_, S, I> {
    fn n_params(&self) -> usize {
        self.n_params
    }
    fn n_outputs(&self) -> usize {
        self.n_outputs
    }
    fn root(&self) -> I {
        self.root
    }
    fn n_nodes(&self) -> usize {
        self.nodes.len()
    }
    fn node(&self, i: usize) -> Option<[I; 3]> {
        self.nodes.get(i).copied()
    }
    fn leaf(&self, i: usize) -> Option<[I; 3]> {
        self.leaves.get(i).copied()
    }
    fn entry(&self, i: usize) -> Option<I> {
        self.entries.get(i).copied()
    }
    fn region_start(&self, r: usize) -> Option<I> {
        self.region_start.get(r).copied()
    }
    fn facet(&self, i: usize) -> Option<I> {
        self.facets.get(i).copied()
    }
    fn region_law(&self, r: usize) -> Option<I> {
        self.region_law.get(r).copied()
    }
    fn hyperplane(&self, h: usize) -> Option<[I; 2]> {
        self.hyperplanes.get(h).copied()
    }
    fn law(&self, law: usize, out: usize) -> Option<I> {
        if out >= self.n_outputs {
            return None;
        }
        self.laws
            .get(law.checked_mul(self.n_outputs)?.checked_add(out)?)
            .copied()
    }
    fn row(&self, r: usize, j: usize) -> Option<S> {
        let w = self.n_params + 1;
        if j >= w {
            return None;
        }
        self.rows.get(r.checked_mul(w)?.checked_add(j)?).copied()
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
        let w = self.n_params + 1;
        if j >= w {
            return None;
        }
        self.hull.get(i.checked_mul(w)?.checked_add(j)?).copied()
    }
    fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
        Some((*self.theta_lb.get(j)?, *self.theta_ub.get(j)?))
    }
    fn output_bounds(&self, out: usize) -> Option<[I; 2]> {
        self.bounds.get(out).copied()
    }
}

/// [`ListAccess`] seen through [`Common`] (the evaluation's shared parts).
struct ViaLists<'t, T: ?Sized>(&'t T);

impl<S: Scalar, I: TreeIndex, T: ListAccess<S, I> + ?Sized> Common<S, I> for ViaLists<'_, T> {
    fn n_params(&self) -> usize {
        ListAccess::n_params(self.0)
    }
    fn n_outputs(&self) -> usize {
        ListAccess::n_outputs(self.0)
    }
    fn law(&self, law: usize, out: usize) -> Option<I> {
        ListAccess::law(self.0, law, out)
    }
    fn row(&self, r: usize, j: usize) -> Option<S> {
        ListAccess::row(self.0, r, j)
    }
    fn row_slice(&self, r: usize) -> Option<&[S]> {
        ListAccess::row_slice(self.0, r)
    }
    fn n_hull(&self) -> usize {
        ListAccess::n_hull(self.0)
    }
    fn hull(&self, i: usize, j: usize) -> Option<S> {
        ListAccess::hull(self.0, i, j)
    }
    fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
        ListAccess::theta_bounds(self.0, j)
    }
    fn output_bounds(&self, out: usize) -> Option<[I; 2]> {
        ListAccess::output_bounds(self.0, out)
    }
}

/// What [`evaluate_lists`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ListEvaluation<I = u16> {
    /// The law used.
    pub law: I,
    /// `theta` was outside the explored set (outside the box or the hull):
    /// the output is a clamped law of a region near its projection.
    pub outside: bool,
    /// Tree nodes visited.
    pub steps: u16,
    /// Hyperplanes evaluated in the leaf's region tests.
    pub tests: u16,
}

/// Affine row `r` at `th`: the accessor's [`ListAccess::row_value`], else
/// entry by entry (the same operations in the same order).
#[inline]
fn row_value<S: Scalar, I: TreeIndex, T: ListAccess<S, I> + ?Sized>(
    t: &ViaLists<'_, T>,
    th: &[S],
    r: usize,
) -> Result<S, Error> {
    match t.0.row_value(r, th) {
        Some(v) => Ok(v),
        None => row_at(t, th, r),
    }
}

/// Output `o` of law `l` at `th`, clamped to the output's bounds (the
/// tree's `output`, rows read through [`row_value`]).
fn output_lists<S: Scalar, I: TreeIndex, T: ListAccess<S, I> + ?Sized>(
    t: &ViaLists<'_, T>,
    th: &[S],
    l: I,
    o: usize,
) -> Result<S, Error> {
    let r = t.0.law(l.index(), o).ok_or(Error::OutOfRange)?.index();
    let mut v = row_value(t, th, r)?;
    let [lo, hi] = t.0.output_bounds(o).ok_or(Error::OutOfRange)?;
    if lo != I::NO_ROW {
        v = v.max(row_value(t, th, lo.index())?);
    }
    if hi != I::NO_ROW {
        v = v.min(row_value(t, th, hi.index())?);
    }
    Ok(v)
}

/// `(r1(theta), r2(theta))` for hyperplane `h`.
#[inline]
fn sides<S: Scalar, I: TreeIndex, T: ListAccess<S, I> + ?Sized>(
    t: &ViaLists<'_, T>,
    th: &[S],
    h: usize,
) -> Result<(S, S), Error> {
    let [r1, r2] = t.0.hyperplane(h).ok_or(Error::OutOfRange)?;
    let a = row_value(t, th, r1.index())?;
    let b = if r2 == I::NO_ROW {
        S::ZERO
    } else {
        row_value(t, th, r2.index())?
    };
    Ok((a, b))
}

/// Whether `th` satisfies every facet of region `r` (a point on a facet's
/// hyperplane satisfies it from both sides), and the facets evaluated (the
/// test stops at the first violated one).
fn contains<S: Scalar, I: TreeIndex, T: ListAccess<S, I> + ?Sized>(
    t: &ViaLists<'_, T>,
    th: &[S],
    r: usize,
) -> Result<(bool, usize), Error> {
    let start = t.0.region_start(r).ok_or(Error::OutOfRange)?.index();
    let end =
        t.0.region_start(r.checked_add(1).ok_or(Error::OutOfRange)?)
            .ok_or(Error::OutOfRange)?
            .index();
    if start > end {
        return Err(Error::OutOfRange);
    }
    for i in start..end {
        let f = t.0.facet(i).ok_or(Error::OutOfRange)?;
        let (a, b) = sides(t, th, f.payload().index())?;
        let inside = if f.is_leaf() { a >= b } else { a <= b };
        if !inside {
            return Ok((false, i - start + 1));
        }
    }
    Ok((true, end - start))
}

/// Locates `theta` with the candidate-list tables and writes the law's
/// outputs, clamped to their bounds, into `z`. `scratch` (at least `p`
/// entries, caller-owned) holds `theta` projected onto the parameter box.
///
/// No allocation, no panic: dimension mismatches, a non-finite `theta`
/// and corrupted tables ([`Error::OutOfRange`]) are errors. The work is
/// bounded by the tables: the tree's depth in hyperplanes, then the facets
/// of the regions one leaf lists (the builder's statistics count the
/// worst case for built tables).
pub fn evaluate_lists<S: Scalar, I: TreeIndex, T: ListAccess<S, I> + ?Sized>(
    tables: &T,
    theta: &[S],
    scratch: &mut [S],
    z: &mut [S],
) -> Result<ListEvaluation<I>, Error> {
    let t = &ViaLists(tables);
    let (th, outside) = project(t, theta, scratch, z.len())?;
    let mut code = tables.root();
    let mut steps: usize = 0;
    let limit = tables.n_nodes();
    while !code.is_leaf() {
        if steps > limit {
            return Err(Error::OutOfRange); // a cycle: corrupted tables
        }
        let [h, le, gt] = tables.node(code.index()).ok_or(Error::OutOfRange)?;
        let (a, b) = sides(t, th, h.index())?;
        code = if a <= b { le } else { gt };
        steps += 1;
    }
    let [first, end, last] = tables
        .leaf(code.payload().index())
        .ok_or(Error::OutOfRange)?;
    let (first, end) = (first.index(), end.index());
    if first > end {
        return Err(Error::OutOfRange);
    }
    let mut law = last;
    let mut tests: usize = 0;
    for i in first..end {
        let r = tables.entry(i).ok_or(Error::OutOfRange)?;
        let (inside, n) = contains(t, th, r.index())?;
        tests += n;
        if inside {
            law = tables.region_law(r.index()).ok_or(Error::OutOfRange)?;
            break;
        }
    }
    for (o, zo) in z.iter_mut().enumerate() {
        *zo = output_lists(t, th, law, o)?;
    }
    Ok(ListEvaluation {
        law,
        outside,
        steps: u16::try_from(steps).unwrap_or(u16::MAX),
        tests: u16::try_from(tests).unwrap_or(u16::MAX),
    })
}
