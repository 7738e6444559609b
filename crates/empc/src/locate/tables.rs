//! The owned candidate-list tables ([`ListTables`]) and their index widths.

use crate::eval::{ListEvaluation, ListSlices, NO_ROW, TreeIndex, WIDE_NO_ROW, evaluate_lists};
use kestrel_core::Scalar;

/// Owned candidate-list tables in scalar `S` with index type `X` (`u32`
/// as built, `u16` after [`ListTables::narrow`]); the fields are those of
/// [`ListSlices`], which [`ListTables::tables`] borrows.
#[derive(Clone, Debug, PartialEq)]
pub struct ListTables<S, X = u32> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code.
    pub root: X,
    /// Tree nodes `[hyperplane, child if r1 <= r2, child otherwise]`.
    pub nodes: Vec<[X; 3]>,
    /// Leaves `[first entry, end entry, final law]`.
    pub leaves: Vec<[X; 3]>,
    /// The regions listed by the leaves.
    pub entries: Vec<X>,
    /// Offsets of every region's facets (`regions + 1` entries).
    pub region_start: Vec<X>,
    /// Facets: hyperplane index, `LEAF` bit for the side `r1 >= r2`.
    pub facets: Vec<X>,
    /// The law of every region.
    pub region_law: Vec<X>,
    /// Hyperplanes `[r1, r2]`.
    pub hyperplanes: Vec<[X; 2]>,
    /// Laws, `k` row indices each.
    pub laws: Vec<X>,
    /// Affine rows, `p + 1` entries each.
    pub rows: Vec<S>,
    /// Explored set rows, `p + 1` entries each.
    pub hull: Vec<S>,
    /// Parameter lower bounds.
    pub theta_lb: Vec<S>,
    /// Parameter upper bounds.
    pub theta_ub: Vec<S>,
    /// Per output: rows of the lower and upper bound.
    pub bounds: Vec<[X; 2]>,
}

impl<S: Scalar, X: TreeIndex> ListTables<S, X> {
    /// Borrowed tables for [`evaluate_lists`].
    pub fn tables(&self) -> ListSlices<'_, S, X> {
        ListSlices {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: self.root,
            nodes: &self.nodes,
            leaves: &self.leaves,
            entries: &self.entries,
            region_start: &self.region_start,
            facets: &self.facets,
            region_law: &self.region_law,
            hyperplanes: &self.hyperplanes,
            laws: &self.laws,
            rows: &self.rows,
            hull: &self.hull,
            theta_lb: &self.theta_lb,
            theta_ub: &self.theta_ub,
            bounds: &self.bounds,
        }
    }

    /// The same tables in another scalar (rounded through `f64`).
    pub fn cast<T: Scalar>(&self) -> ListTables<T, X> {
        let c = |v: &Vec<S>| v.iter().map(|x| T::from_f64(x.to_f64())).collect();
        ListTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: self.root,
            nodes: self.nodes.clone(),
            leaves: self.leaves.clone(),
            entries: self.entries.clone(),
            region_start: self.region_start.clone(),
            facets: self.facets.clone(),
            region_law: self.region_law.clone(),
            hyperplanes: self.hyperplanes.clone(),
            laws: self.laws.clone(),
            rows: c(&self.rows),
            hull: c(&self.hull),
            theta_lb: c(&self.theta_lb),
            theta_ub: c(&self.theta_ub),
            bounds: self.bounds.clone(),
        }
    }

    /// Storage in bytes with `scalar_bytes` per number and the index
    /// type's size per index.
    pub fn bytes(&self, scalar_bytes: usize) -> usize {
        let numbers = self.rows.len() + self.hull.len() + self.theta_lb.len() + self.theta_ub.len();
        let indices = 3 * self.nodes.len()
            + 3 * self.leaves.len()
            + self.entries.len()
            + self.region_start.len()
            + self.facets.len()
            + self.region_law.len()
            + 2 * self.hyperplanes.len()
            + self.laws.len()
            + 2 * self.bounds.len();
        numbers * scalar_bytes + indices * core::mem::size_of::<X>()
    }

    /// Evaluates at `theta` in the tables' scalar (named after the usual
    /// `f64` use; allocates a scratch vector: in a loop, borrow
    /// [`ListTables::tables`] and call [`evaluate_lists`]).
    pub fn evaluate_f64(
        &self,
        theta: &[S],
        z: &mut [S],
    ) -> Result<ListEvaluation<X>, kestrel_core::Error> {
        let mut scratch = vec![S::ZERO; theta.len()];
        evaluate_lists(&self.tables(), theta, &mut scratch, z)
    }
}

/// A child code or facet (`u32`, top bit a flag) as `u16`, if it fits;
/// the flag moves to `u16`'s top bit.
fn narrow_flagged(v: u32) -> Option<u16> {
    let x = u16::try_from(v & !u32::LEAF).ok()?;
    if x & u16::LEAF != 0 {
        return None;
    }
    Some(if v & u32::LEAF != 0 { x | u16::LEAF } else { x })
}

/// A row index as `u16` (`WIDE_NO_ROW` becomes `NO_ROW`), if it fits.
fn narrow_row(v: u32) -> Option<u16> {
    if v == WIDE_NO_ROW {
        return Some(NO_ROW);
    }
    u16::try_from(v).ok().filter(|&x| x != NO_ROW)
}

/// A plain index (offset, law, region, hyperplane) as `u16`, if it fits.
fn narrow_plain(v: u32) -> Option<u16> {
    u16::try_from(v).ok().filter(|&x| x != NO_ROW)
}

impl<S: Clone> ListTables<S, u32> {
    /// The same tables with `u16` indices, if every index fits (at most
    /// 32767 nodes, leaves and hyperplanes, 65534 rows, laws, entries and
    /// facets); `None` otherwise.
    pub fn narrow(&self) -> Option<ListTables<S, u16>> {
        fn each(v: &[u32], f: fn(u32) -> Option<u16>) -> Option<Vec<u16>> {
            v.iter().map(|&x| f(x)).collect()
        }
        fn each_n<const N: usize>(
            v: &[[u32; N]],
            f: [fn(u32) -> Option<u16>; N],
        ) -> Option<Vec<[u16; N]>> {
            v.iter()
                .map(|n| {
                    let mut out = [0u16; N];
                    for ((o, &x), g) in out.iter_mut().zip(n).zip(f) {
                        *o = g(x)?;
                    }
                    Some(out)
                })
                .collect()
        }
        Some(ListTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: narrow_flagged(self.root)?,
            nodes: each_n(&self.nodes, [narrow_plain, narrow_flagged, narrow_flagged])?,
            leaves: each_n(&self.leaves, [narrow_plain, narrow_plain, narrow_plain])?,
            entries: each(&self.entries, narrow_plain)?,
            region_start: each(&self.region_start, narrow_plain)?,
            facets: each(&self.facets, narrow_flagged)?,
            region_law: each(&self.region_law, narrow_plain)?,
            hyperplanes: each_n(&self.hyperplanes, [narrow_row, narrow_row])?,
            laws: each(&self.laws, narrow_row)?,
            rows: self.rows.clone(),
            hull: self.hull.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            bounds: each_n(&self.bounds, [narrow_row, narrow_row])?,
        })
    }
}
