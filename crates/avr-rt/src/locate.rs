//! Candidate-list point location from program memory: kestrel-empc's
//! `no_std` [`kestrel_empc::evaluate_lists`] reading its tables through
//! [`FlashLists`], a [`ListAccess`] accessor over one flat byte table (a
//! [`crate::progmem::FarTable`] or [`crate::progmem::FarChunks`] on the
//! AVR, read with `ELPM`; any [`TableRead`] on the host), as
//! [`crate::explicit::FlashTree`] serves the exact tree.
//!
//! Byte layout ([`ListLayout`]), little-endian, in this order: nodes
//! (`3 x u16`), leaves (`3 x u16`), list entries (`u16`), region starts
//! (`u16`, regions + 1), facets (`u16`), region laws (`u16`), hyperplanes
//! (`2 x u16`), laws (`k x u16` each), output bounds (`2 x u16` per
//! output), then the numbers (4 bytes each: `f32`, or the raw bits of a
//! Q15.16): affine rows (`p + 1` each), the explored set's rows (`p + 1`
//! each), the parameter lower bounds, the upper bounds. Offsets are `u32`:
//! the tables may exceed 64 kB (the ATmega2560 has 256 kB of flash).
//! `list_bytes` / `list_bytes_with` (feature `std`) write it from `u16`
//! [`ListSlices`].
//!
//! ```
//! use kestrel_avr_rt::locate::{FlashLists, list_bytes};
//! use kestrel_empc::{LEAF, ListSlices, NO_ROW, evaluate_lists};
//! // One parameter, one output; a root node splitting at theta = 0 into
//! // two leaves with empty lists: law 0 (z = -theta) left, law 1 (z = 0) right.
//! let t = ListSlices::<f32> {
//!     n_params: 1, n_outputs: 1, root: 0,
//!     nodes: &[[0, LEAF, LEAF | 1]], leaves: &[[0, 0, 0], [0, 0, 1]],
//!     entries: &[], region_start: &[0], facets: &[], region_law: &[],
//!     hyperplanes: &[[2, NO_ROW]], laws: &[0, 1],
//!     rows: &[-1.0, 0.0, 0.0, 0.0, 1.0, 0.0], hull: &[],
//!     theta_lb: &[-1.0], theta_ub: &[1.0], bounds: &[[NO_ROW, NO_ROW]],
//! };
//! let (bytes, layout) = list_bytes(&t);
//! let flash = FlashLists::<_, f32>::new(&bytes[..], layout).unwrap();
//! let (mut scratch, mut z) = ([0.0f32], [0.0f32]);
//! let e = evaluate_lists(&flash, &[-0.5], &mut scratch, &mut z).unwrap();
//! assert_eq!((z[0], e.law), (0.5, 0));
//! ```

use crate::explicit::FlashNumber;
use crate::progmem::TableRead;
use kestrel_core::Error;
use kestrel_empc::ListAccess;
#[cfg(feature = "std")]
use kestrel_empc::ListSlices;

/// Counts of the candidate-list tables (the generated constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ListLayout {
    /// Parameters `p`.
    pub n_params: u16,
    /// Outputs `k`.
    pub n_outputs: u16,
    /// The root child code.
    pub root: u16,
    /// Tree nodes.
    pub n_nodes: u16,
    /// Leaves.
    pub n_leaves: u16,
    /// List entries.
    pub n_entries: u16,
    /// Regions (the region starts hold one more).
    pub n_regions: u16,
    /// Facet references.
    pub n_facets: u16,
    /// Hyperplanes.
    pub n_hyperplanes: u16,
    /// Laws (`k` row indices each).
    pub n_laws: u16,
    /// Affine rows (`p + 1` numbers each).
    pub n_rows: u16,
    /// Rows of the explored set (`p + 1` numbers each).
    pub n_hull: u16,
}

/// Byte offsets of the sections (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Offsets {
    leaves: u32,
    entries: u32,
    starts: u32,
    facets: u32,
    region_law: u32,
    hyperplanes: u32,
    laws: u32,
    bounds: u32,
    rows: u32,
    hull: u32,
    lb: u32,
    ub: u32,
    end: u32,
}

impl ListLayout {
    /// The sections' offsets and the total length, `None` on overflow.
    fn offsets(&self) -> Option<Offsets> {
        let c = |n: u16, bytes: u32| u32::from(n).checked_mul(bytes);
        let add = |a: u32, b: Option<u32>| a.checked_add(b?);
        let k = u32::from(self.n_outputs);
        let w = u32::from(self.n_params) + 1;
        let leaves = c(self.n_nodes, 6)?;
        let entries = add(leaves, c(self.n_leaves, 6))?;
        let starts = add(entries, c(self.n_entries, 2))?;
        let facets = add(starts, (u32::from(self.n_regions) + 1).checked_mul(2))?;
        let region_law = add(facets, c(self.n_facets, 2))?;
        let hyperplanes = add(region_law, c(self.n_regions, 2))?;
        let laws = add(hyperplanes, c(self.n_hyperplanes, 4))?;
        let bounds = add(laws, c(self.n_laws, 2)?.checked_mul(k))?;
        let rows = add(bounds, k.checked_mul(4))?;
        let hull = add(rows, c(self.n_rows, 4)?.checked_mul(w))?;
        let lb = add(hull, c(self.n_hull, 4)?.checked_mul(w))?;
        let ub = add(lb, c(self.n_params, 4))?;
        let end = add(ub, c(self.n_params, 4))?;
        Some(Offsets {
            leaves,
            entries,
            starts,
            facets,
            region_law,
            hyperplanes,
            laws,
            bounds,
            rows,
            hull,
            lb,
            ub,
            end,
        })
    }
    /// Total bytes (4-byte numbers), `None` if it overflows `u32`.
    pub fn bytes(&self) -> Option<u32> {
        self.offsets().map(|o| o.end)
    }
}

/// [`ListAccess`] over one flat table in the layout of [`ListLayout`];
/// every read is bounds-checked (`None` out of range, never a panic).
#[derive(Clone, Copy, Debug)]
pub struct FlashLists<T, S> {
    table: T,
    layout: ListLayout,
    at: Offsets,
    _s: core::marker::PhantomData<S>,
}

impl<T: TableRead, S: FlashNumber> FlashLists<T, S> {
    /// The accessor; [`Error::DimensionMismatch`] if the table's length is
    /// not the layout's, [`Error::InvalidArgument`] for a layout whose size
    /// overflows `u32`.
    pub fn new(table: T, layout: ListLayout) -> Result<Self, Error> {
        let Some(at) = layout.offsets() else {
            return Err(Error::InvalidArgument("a layout whose size overflows u32"));
        };
        let len = table.len_bytes();
        if len != at.end {
            return Err(Error::DimensionMismatch {
                expected: at.end as usize,
                found: len as usize,
            });
        }
        Ok(FlashLists {
            table,
            layout,
            at,
            _s: core::marker::PhantomData,
        })
    }
    /// The layout.
    pub fn layout(&self) -> &ListLayout {
        &self.layout
    }
    /// `u16` number `i` of a section of `n` entries of `w` `u16` each.
    #[inline]
    fn words<const W: usize, const B: usize>(
        &self,
        base: u32,
        n: u16,
        i: usize,
    ) -> Option<[u16; W]> {
        if i >= usize::from(n) {
            return None;
        }
        let b: [u8; B] = self.table.read_array(base + (B as u32) * i as u32)?;
        let mut out = [0u16; W];
        for (j, o) in out.iter_mut().enumerate() {
            *o = u16::from_le_bytes([*b.get(2 * j)?, *b.get(2 * j + 1)?]);
        }
        Some(out)
    }
    #[inline]
    fn word(&self, base: u32, n: u16, i: usize) -> Option<u16> {
        if i >= usize::from(n) {
            return None;
        }
        self.table.read_u16(base + 2 * i as u32)
    }
    #[inline]
    fn number(&self, base: u32, count: u16, i: usize, j: usize) -> Option<S> {
        let w = usize::from(self.layout.n_params) + 1;
        if i >= usize::from(count) || j >= w {
            return None;
        }
        let at = base + 4 * (i as u32 * w as u32 + j as u32);
        self.table.read_array::<4>(at).map(S::from_le)
    }
}

impl<T: TableRead, S: FlashNumber> ListAccess<S, u16> for FlashLists<T, S> {
    fn n_params(&self) -> usize {
        usize::from(self.layout.n_params)
    }
    fn n_outputs(&self) -> usize {
        usize::from(self.layout.n_outputs)
    }
    fn root(&self) -> u16 {
        self.layout.root
    }
    fn n_nodes(&self) -> usize {
        usize::from(self.layout.n_nodes)
    }
    fn node(&self, i: usize) -> Option<[u16; 3]> {
        self.words::<3, 6>(0, self.layout.n_nodes, i)
    }
    fn leaf(&self, i: usize) -> Option<[u16; 3]> {
        self.words::<3, 6>(self.at.leaves, self.layout.n_leaves, i)
    }
    fn entry(&self, i: usize) -> Option<u16> {
        self.word(self.at.entries, self.layout.n_entries, i)
    }
    fn region_start(&self, r: usize) -> Option<u16> {
        self.word(self.at.starts, self.layout.n_regions.checked_add(1)?, r)
    }
    fn facet(&self, i: usize) -> Option<u16> {
        self.word(self.at.facets, self.layout.n_facets, i)
    }
    fn region_law(&self, r: usize) -> Option<u16> {
        self.word(self.at.region_law, self.layout.n_regions, r)
    }
    fn hyperplane(&self, h: usize) -> Option<[u16; 2]> {
        self.words::<2, 4>(self.at.hyperplanes, self.layout.n_hyperplanes, h)
    }
    fn law(&self, law: usize, out: usize) -> Option<u16> {
        let k = usize::from(self.layout.n_outputs);
        if law >= usize::from(self.layout.n_laws) || out >= k {
            return None;
        }
        self.table
            .read_u16(self.at.laws + 2 * (law * k + out) as u32)
    }
    fn row(&self, r: usize, j: usize) -> Option<S> {
        self.number(self.at.rows, self.layout.n_rows, r, j)
    }
    fn row_value(&self, r: usize, theta: &[S]) -> Option<S> {
        let p = usize::from(self.layout.n_params);
        if r >= usize::from(self.layout.n_rows) || theta.len() != p {
            return None;
        }
        let base = self.at.rows + r as u32 * (4 * (p as u32 + 1));
        let mut acc = S::from_le(self.table.read_array::<4>(base + 4 * p as u32)?);
        let mut at = base;
        for t in theta {
            acc = acc.mul_add(S::from_le(self.table.read_array::<4>(at)?), *t);
            at += 4;
        }
        Some(acc)
    }
    fn n_hull(&self) -> usize {
        usize::from(self.layout.n_hull)
    }
    fn hull(&self, i: usize, j: usize) -> Option<S> {
        self.number(self.at.hull, self.layout.n_hull, i, j)
    }
    fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
        if j >= usize::from(self.layout.n_params) {
            return None;
        }
        let lb = self.table.read_array::<4>(self.at.lb + 4 * j as u32)?;
        let ub = self.table.read_array::<4>(self.at.ub + 4 * j as u32)?;
        Some((S::from_le(lb), S::from_le(ub)))
    }
    fn output_bounds(&self, out: usize) -> Option<[u16; 2]> {
        self.words::<2, 4>(self.at.bounds, self.layout.n_outputs, out)
    }
}

/// The flash table and its layout for `u16` [`ListSlices`] with `f32`
/// numbers (design time); [`list_bytes_with`] for other numbers.
#[cfg(feature = "std")]
pub fn list_bytes(t: &ListSlices<'_, f32, u16>) -> (Vec<u8>, ListLayout) {
    list_bytes_with(t, f32::to_le_bytes)
}

/// The flash table and its layout for `u16` [`ListSlices`], each number
/// written by `le` (its 4 little-endian bytes as [`FlashNumber::from_le`]
/// reads them back: e.g. the raw bits of a `Q16Mac`). Counts beyond `u16`
/// cannot be `u16` tables; the layout's counts saturate and
/// [`FlashLists::new`] then refuses the table.
#[cfg(feature = "std")]
pub fn list_bytes_with<S: Copy>(
    t: &ListSlices<'_, S, u16>,
    le: impl Fn(S) -> [u8; 4],
) -> (Vec<u8>, ListLayout) {
    let n = |v: usize| u16::try_from(v).unwrap_or(u16::MAX);
    let w = t.n_params + 1;
    let layout = ListLayout {
        n_params: n(t.n_params),
        n_outputs: n(t.n_outputs),
        root: t.root,
        n_nodes: n(t.nodes.len()),
        n_leaves: n(t.leaves.len()),
        n_entries: n(t.entries.len()),
        n_regions: n(t.region_start.len().saturating_sub(1)),
        n_facets: n(t.facets.len()),
        n_hyperplanes: n(t.hyperplanes.len()),
        n_laws: n(t.laws.len() / t.n_outputs.max(1)),
        n_rows: n(t.rows.len() / w),
        n_hull: n(t.hull.len() / w),
    };
    let mut b = Vec::new();
    let words = t
        .nodes
        .iter()
        .flatten()
        .chain(t.leaves.iter().flatten())
        .chain(t.entries)
        .chain(t.region_start)
        .chain(t.facets)
        .chain(t.region_law)
        .chain(t.hyperplanes.iter().flatten())
        .chain(t.laws)
        .chain(t.bounds.iter().flatten());
    for v in words {
        b.extend(v.to_le_bytes());
    }
    for v in t
        .rows
        .iter()
        .chain(t.hull)
        .chain(t.theta_lb)
        .chain(t.theta_ub)
    {
        b.extend(le(*v));
    }
    (b, layout)
}

#[cfg(test)]
mod tests;
