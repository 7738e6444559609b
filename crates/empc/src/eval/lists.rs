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

use crate::eval::evaluate::{Common, output, project, row_at};
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

impl<S: Scalar, I: TreeIndex> Common<S, I> for ListSlices<'_, S, I> {
    fn n_params(&self) -> usize {
        self.n_params
    }
    fn n_outputs(&self) -> usize {
        self.n_outputs
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

impl<S: Scalar, I: TreeIndex> ListSlices<'_, S, I> {
    /// `(r1(theta), r2(theta))` for hyperplane `h`.
    #[inline]
    fn sides(&self, th: &[S], h: usize) -> Result<(S, S), Error> {
        let [r1, r2] = *self.hyperplanes.get(h).ok_or(Error::OutOfRange)?;
        let a = row_at(self, th, r1.index())?;
        let b = if r2 == I::NO_ROW {
            S::ZERO
        } else {
            row_at(self, th, r2.index())?
        };
        Ok((a, b))
    }

    /// Whether `th` satisfies every facet of region `r` (a point on a
    /// facet's hyperplane satisfies it from both sides), and the facets
    /// evaluated (the test stops at the first violated one).
    fn contains(&self, th: &[S], r: usize) -> Result<(bool, usize), Error> {
        let start = self.region_start.get(r).ok_or(Error::OutOfRange)?.index();
        let end = self
            .region_start
            .get(r.checked_add(1).ok_or(Error::OutOfRange)?)
            .ok_or(Error::OutOfRange)?
            .index();
        let facets = self.facets.get(start..end).ok_or(Error::OutOfRange)?;
        for (i, f) in facets.iter().enumerate() {
            let (a, b) = self.sides(th, f.payload().index())?;
            let inside = if f.is_leaf() { a >= b } else { a <= b };
            if !inside {
                return Ok((false, i + 1));
            }
        }
        Ok((true, facets.len()))
    }
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
pub fn evaluate_lists<S: Scalar, I: TreeIndex>(
    tables: &ListSlices<'_, S, I>,
    theta: &[S],
    scratch: &mut [S],
    z: &mut [S],
) -> Result<ListEvaluation<I>, Error> {
    let (th, outside) = project(tables, theta, scratch, z.len())?;
    let mut code = tables.root;
    let mut steps: usize = 0;
    while !code.is_leaf() {
        if steps > tables.nodes.len() {
            return Err(Error::OutOfRange); // a cycle: corrupted tables
        }
        let [h, le, gt] = *tables.nodes.get(code.index()).ok_or(Error::OutOfRange)?;
        let (a, b) = tables.sides(th, h.index())?;
        code = if a <= b { le } else { gt };
        steps += 1;
    }
    let [first, end, last] = *tables
        .leaves
        .get(code.payload().index())
        .ok_or(Error::OutOfRange)?;
    let list = tables
        .entries
        .get(first.index()..end.index())
        .ok_or(Error::OutOfRange)?;
    let mut law = last;
    let mut tests: usize = 0;
    for r in list {
        let (inside, n) = tables.contains(th, r.index())?;
        tests += n;
        if inside {
            law = *tables.region_law.get(r.index()).ok_or(Error::OutOfRange)?;
            break;
        }
    }
    for (o, zo) in z.iter_mut().enumerate() {
        *zo = output(tables, th, law, o)?;
    }
    Ok(ListEvaluation {
        law,
        outside,
        steps: u16::try_from(steps).unwrap_or(u16::MAX),
        tests: u16::try_from(tests).unwrap_or(u16::MAX),
    })
}
