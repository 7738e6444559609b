//! Explicit MPC from program memory: kestrel-empc's `no_std` tree
//! evaluation reading its tables through [`FlashTree`], a
//! [`kestrel_empc::TreeTables`] accessor over one flat byte table (a
//! [`crate::progmem::FarTable`] on the AVR, read with `ELPM`; any
//! [`TableRead`] on the host), and [`EmpcLaw`], the evaluation as a
//! [`ControlLaw`] with `theta = [x; r; throttle]`.
//!
//! Byte layout of the table ([`TreeLayout`]), little-endian, in this order:
//! nodes (`4 x u16` each), laws (`u16` row indices, `k` per law), output
//! bounds (`2 x u16` per output), then the numbers (4 bytes each: `f32`,
//! or the raw bits of a Q15.16): affine rows (`p + 1` each), the explored
//! set's rows (`p + 1` each), the parameter lower bounds, the upper bounds.
//! The firmware design (kestrel-tricopter) writes it.
//!
//! ```
//! use kestrel_avr_rt::explicit::{FlashTree, TreeLayout};
//! use kestrel_empc::{evaluate, LEAF, NO_ROW};
//! // One parameter, one output: z = -theta for theta <= 0, 0 otherwise.
//! let layout = TreeLayout { n_params: 1, n_outputs: 1, root: 0, n_nodes: 1, n_laws: 2, n_rows: 3, n_hull: 0 };
//! let mut bytes = Vec::new();
//! for v in [2u16, NO_ROW, LEAF, LEAF | 1, 0, 1, NO_ROW, NO_ROW] {
//!     bytes.extend(v.to_le_bytes());
//! }
//! for v in [-1.0f32, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 1.0] {
//!     bytes.extend(v.to_le_bytes());
//! }
//! assert_eq!(bytes.len(), layout.bytes(4));
//! let tree = FlashTree::<_, f32>::new(&bytes[..], layout).unwrap();
//! let mut z = [0.0f32];
//! evaluate(&tree, &[-0.5], &mut z).unwrap();
//! assert_eq!(z, [0.5]);
//! ```

#[cfg(feature = "std")]
pub mod quantize;
pub mod tree16;

use crate::law::LawInfo;
use crate::law::pack_theta;
use crate::progmem::TableRead;
use kestrel_core::{ControlLaw, Error, Scalar};
use kestrel_empc::{TreeTables, evaluate};

/// A number stored as 4 little-endian bytes in a flash table.
pub trait FlashNumber: Scalar {
    /// The value of the 4 bytes.
    fn from_le(b: [u8; 4]) -> Self;
}
impl FlashNumber for f32 {
    #[inline]
    fn from_le(b: [u8; 4]) -> Self {
        f32::from_le_bytes(b)
    }
}
impl FlashNumber for kestrel_core::Q16 {
    #[inline]
    fn from_le(b: [u8; 4]) -> Self {
        kestrel_core::Fixed(i32::from_le_bytes(b))
    }
}
impl FlashNumber for crate::mac::Q16Mac {
    #[inline]
    fn from_le(b: [u8; 4]) -> Self {
        Self::from_bits(i32::from_le_bytes(b))
    }
}

/// Counts of the explicit controller's tables (the generated constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TreeLayout {
    /// Parameters `p`.
    pub n_params: usize,
    /// Outputs `k`.
    pub n_outputs: usize,
    /// The root child code.
    pub root: u16,
    /// Tree nodes.
    pub n_nodes: usize,
    /// Laws (`k` row indices each).
    pub n_laws: usize,
    /// Affine rows (`p + 1` numbers each).
    pub n_rows: usize,
    /// Rows of the explored set (`p + 1` numbers each).
    pub n_hull: usize,
}

impl TreeLayout {
    /// Byte offset of the laws.
    pub const fn laws_at(&self) -> usize {
        8 * self.n_nodes
    }
    /// Byte offset of the output bounds.
    pub const fn bounds_at(&self) -> usize {
        self.laws_at() + 2 * self.n_laws * self.n_outputs
    }
    /// Byte offset of the numbers (affine rows first).
    pub const fn numbers_at(&self) -> usize {
        self.bounds_at() + 4 * self.n_outputs
    }
    /// Numbers stored: rows, explored set, parameter bounds.
    pub const fn n_numbers(&self) -> usize {
        (self.n_rows + self.n_hull) * (self.n_params + 1) + 2 * self.n_params
    }
    /// Total bytes with `scalar_bytes` per number.
    pub const fn bytes(&self, scalar_bytes: usize) -> usize {
        self.numbers_at() + scalar_bytes * self.n_numbers()
    }
    /// [`TreeLayout::bytes`], or `None` if a size overflows `usize` (where
    /// `bytes` would panic or wrap): the check [`FlashTree::new`] makes of a
    /// layout before it trusts its offsets.
    pub const fn checked_bytes(&self, scalar_bytes: usize) -> Option<usize> {
        const fn mul(a: Option<usize>, b: usize) -> Option<usize> {
            match a {
                Some(a) => a.checked_mul(b),
                None => None,
            }
        }
        const fn add(a: Option<usize>, b: Option<usize>) -> Option<usize> {
            match (a, b) {
                (Some(a), Some(b)) => a.checked_add(b),
                _ => None,
            }
        }
        let laws = mul(Some(8), self.n_nodes);
        let bounds = add(laws, mul(mul(Some(2), self.n_laws), self.n_outputs));
        let numbers_at = add(bounds, mul(Some(4), self.n_outputs));
        let w = add(Some(self.n_params), Some(1));
        let rows = match w {
            Some(w) => mul(add(Some(self.n_rows), Some(self.n_hull)), w),
            None => None,
        };
        let numbers = add(rows, mul(Some(2), self.n_params));
        add(numbers_at, mul(numbers, scalar_bytes))
    }
}

/// [`TreeTables`] over one flat table in the layout of [`TreeLayout`].
#[derive(Clone, Copy, Debug)]
pub struct FlashTree<T, S> {
    table: T,
    layout: TreeLayout,
    rows_at: u32,
    hull_at: u32,
    lb_at: u32,
    ub_at: u32,
    _s: core::marker::PhantomData<S>,
}

impl<T: TableRead, S: FlashNumber> FlashTree<T, S> {
    /// The accessor; [`Error::DimensionMismatch`] if the table's length is
    /// not the layout's (4-byte numbers), [`Error::InvalidArgument`] for a
    /// layout whose size overflows ([`TreeLayout::checked_bytes`]).
    pub fn new(table: T, layout: TreeLayout) -> Result<Self, Error> {
        let len = table.len_bytes() as usize;
        let Some(want) = layout.checked_bytes(4) else {
            return Err(Error::InvalidArgument(
                "a layout whose size overflows usize",
            ));
        };
        if len != want {
            return Err(Error::DimensionMismatch {
                expected: want,
                found: len,
            });
        }
        let w = 4 * (layout.n_params + 1);
        let rows_at = layout.numbers_at();
        let hull_at = rows_at + w * layout.n_rows;
        let lb_at = hull_at + w * layout.n_hull;
        let ub_at = lb_at + 4 * layout.n_params;
        Ok(FlashTree {
            table,
            layout,
            rows_at: rows_at as u32,
            hull_at: hull_at as u32,
            lb_at: lb_at as u32,
            ub_at: ub_at as u32,
            _s: core::marker::PhantomData,
        })
    }
    /// The layout.
    pub fn layout(&self) -> &TreeLayout {
        &self.layout
    }
    #[inline]
    fn number(&self, at: u32) -> Option<S> {
        self.table.read_array::<4>(at).map(S::from_le)
    }
    #[inline]
    fn entry(&self, base: u32, count: usize, i: usize, j: usize) -> Option<S> {
        let w = self.layout.n_params + 1;
        if i >= count || j >= w {
            return None;
        }
        self.number(base + 4 * (i * w + j) as u32)
    }
}

impl<T: TableRead, S: FlashNumber> TreeTables<S> for FlashTree<T, S> {
    fn n_params(&self) -> usize {
        self.layout.n_params
    }
    fn n_outputs(&self) -> usize {
        self.layout.n_outputs
    }
    fn n_nodes(&self) -> usize {
        self.layout.n_nodes
    }
    fn root(&self) -> u16 {
        self.layout.root
    }
    fn node(&self, i: usize) -> Option<[u16; 4]> {
        if i >= self.layout.n_nodes {
            return None;
        }
        let b: [u8; 8] = self.table.read_array(8 * i as u32)?;
        Some([
            u16::from_le_bytes([b[0], b[1]]),
            u16::from_le_bytes([b[2], b[3]]),
            u16::from_le_bytes([b[4], b[5]]),
            u16::from_le_bytes([b[6], b[7]]),
        ])
    }
    fn law(&self, law: usize, out: usize) -> Option<u16> {
        let k = self.layout.n_outputs;
        if law >= self.layout.n_laws || out >= k {
            return None;
        }
        self.table
            .read_u16((self.layout.laws_at() + 2 * (law * k + out)) as u32)
    }
    fn row(&self, r: usize, j: usize) -> Option<S> {
        self.entry(self.rows_at, self.layout.n_rows, r, j)
    }
    fn n_hull(&self) -> usize {
        self.layout.n_hull
    }
    fn hull(&self, i: usize, j: usize) -> Option<S> {
        self.entry(self.hull_at, self.layout.n_hull, i, j)
    }
    fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
        if j >= self.layout.n_params {
            return None;
        }
        Some((
            self.number(self.lb_at + 4 * j as u32)?,
            self.number(self.ub_at + 4 * j as u32)?,
        ))
    }
    fn output_bounds(&self, out: usize) -> Option<[u16; 2]> {
        if out >= self.layout.n_outputs {
            return None;
        }
        let b: [u8; 4] = self
            .table
            .read_array((self.layout.bounds_at() + 4 * out) as u32)?;
        Some([
            u16::from_le_bytes([b[0], b[1]]),
            u16::from_le_bytes([b[2], b[3]]),
        ])
    }
}

/// The explicit MPC law: `theta = [x; r]` (`P` parameters, the first `nx`
/// the state), the tree's first `NU` outputs are the input moves.
///
/// Outside the explored set the evaluation is kestrel-empc's safe one (the
/// clamped law of the nearest region); [`EmpcLaw::outside`] counts it.
#[derive(Clone, Debug)]
pub struct EmpcLaw<S, T, const P: usize, const NU: usize> {
    tables: T,
    nx: usize,
    steps: u16,
    outside: u32,
    _s: core::marker::PhantomData<S>,
}

impl<S: Scalar, T: TreeTables<S>, const P: usize, const NU: usize> EmpcLaw<S, T, P, NU> {
    /// The law over `tables`; [`Error::DimensionMismatch`] unless the
    /// tables have `P` parameters and `NU` outputs and `nx < P`.
    pub fn new(tables: T, nx: usize) -> Result<Self, Error> {
        if tables.n_params() != P {
            return Err(Error::DimensionMismatch {
                expected: P,
                found: tables.n_params(),
            });
        }
        if tables.n_outputs() != NU {
            return Err(Error::DimensionMismatch {
                expected: NU,
                found: tables.n_outputs(),
            });
        }
        if nx >= P {
            return Err(Error::DimensionMismatch {
                expected: P - 1,
                found: nx,
            });
        }
        Ok(EmpcLaw {
            tables,
            nx,
            steps: 0,
            outside: 0,
            _s: core::marker::PhantomData,
        })
    }
    /// Periods whose parameter was outside the explored set.
    pub fn outside(&self) -> u32 {
        self.outside
    }
    /// The tables.
    pub fn tables(&self) -> &T {
        &self.tables
    }
}

impl<S: Scalar, T: TreeTables<S>, const P: usize, const NU: usize> ControlLaw
    for EmpcLaw<S, T, P, NU>
{
    type Scalar = S;
    crate::law::parametric_law_sizes!();
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        let theta: [S; P] = pack_theta(self.nx, NU, x, r, u)?;
        let e = evaluate(&self.tables, &theta, u)?;
        self.steps = e.steps;
        if e.outside {
            self.outside = self.outside.saturating_add(1);
        }
        Ok(())
    }
}

impl<S: Scalar, T: TreeTables<S>, const P: usize, const NU: usize> LawInfo
    for EmpcLaw<S, T, P, NU>
{
    /// The tree nodes visited in the last period.
    fn iterations(&self) -> u16 {
        self.steps
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_empc::{LEAF, NO_ROW, SliceTables};

    static NODES: [[u16; 4]; 1] = [[2, NO_ROW, LEAF, LEAF | 1]];
    static LAWS: [u16; 2] = [0, 1];
    static ROWS: [f32; 6] = [-1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    static BOUNDS: [[u16; 2]; 1] = [[NO_ROW, NO_ROW]];

    fn slice() -> SliceTables<'static, f32> {
        SliceTables {
            n_params: 1,
            n_outputs: 1,
            root: 0,
            nodes: &NODES,
            laws: &LAWS,
            rows: &ROWS,
            hull: &[],
            theta_lb: &[-1.0],
            theta_ub: &[1.0],
            bounds: &BOUNDS,
        }
    }

    fn bytes() -> (Vec<u8>, TreeLayout) {
        let l = TreeLayout {
            n_params: 1,
            n_outputs: 1,
            root: 0,
            n_nodes: 1,
            n_laws: 2,
            n_rows: 3,
            n_hull: 0,
        };
        let mut b = Vec::new();
        for v in NODES
            .iter()
            .flatten()
            .chain(&LAWS)
            .chain(BOUNDS.iter().flatten())
        {
            b.extend(v.to_le_bytes());
        }
        for v in ROWS.iter().chain(&[-1.0, 1.0]) {
            b.extend(v.to_le_bytes());
        }
        (b, l)
    }

    #[test]
    fn flash_tree_reads_what_the_slice_tables_hold() {
        let (b, l) = bytes();
        let f = FlashTree::<_, f32>::new(&b[..], l).unwrap();
        let s = slice();
        assert_eq!(f.node(0), s.node(0));
        assert_eq!(f.node(1), None);
        for law in 0..3 {
            assert_eq!(f.law(law, 0), s.law(law, 0));
        }
        for r in 0..4 {
            for j in 0..3 {
                assert_eq!(f.row(r, j), s.row(r, j));
            }
        }
        assert_eq!(f.theta_bounds(0), s.theta_bounds(0));
        assert_eq!(f.theta_bounds(1), None);
        assert_eq!(f.output_bounds(0), s.output_bounds(0));
        assert_eq!(f.output_bounds(1), None);
    }

    /// Found by fuzzing (`fuzz/regressions/flash_tree/crash-*`): counts
    /// whose byte size overflows `usize` panicked in `TreeLayout::bytes`
    /// (or wrapped to a small size in a release build).
    #[test]
    fn a_layout_whose_size_overflows_is_an_error() {
        let (b, l) = bytes();
        for huge in [
            TreeLayout {
                n_laws: 1 << 40,
                n_outputs: 1 << 40,
                ..l
            },
            TreeLayout {
                n_nodes: usize::MAX / 4,
                ..l
            },
            TreeLayout {
                n_params: usize::MAX,
                ..l
            },
        ] {
            assert!(huge.checked_bytes(4).is_none());
            assert!(matches!(
                FlashTree::<_, f32>::new(&b[..], huge),
                Err(Error::InvalidArgument(_))
            ));
        }
        assert_eq!(l.checked_bytes(4), Some(l.bytes(4)));
    }

    #[test]
    fn wrong_length_is_an_error() {
        let (b, l) = bytes();
        assert!(matches!(
            FlashTree::<_, f32>::new(&b[..b.len() - 1], l),
            Err(Error::DimensionMismatch { .. })
        ));
    }

    #[test]
    fn corrupted_node_is_an_error_not_a_panic() {
        let (good, l) = bytes();
        let tree = |b| FlashTree::<&[u8], f32>::new(b, l).unwrap();
        // P = 2 does not match one parameter; nx must leave a reference.
        assert!(EmpcLaw::<f32, _, 2, 1>::new(tree(&good[..]), 0).is_err());
        assert!(EmpcLaw::<f32, _, 1, 1>::new(tree(&good[..]), 1).is_err());
        let mut bad = good.clone();
        bad[4] = 7; // child "node 7" of a 1-node tree
        bad[5] = 0;
        let mut law = EmpcLaw::<f32, _, 1, 1>::new(tree(&bad[..]), 0).unwrap();
        let mut u = [0.0];
        assert_eq!(law.control(&[], &[-0.5], &mut u), Err(Error::OutOfRange));
        let mut law = EmpcLaw::<f32, _, 1, 1>::new(tree(&good[..]), 0).unwrap();
        assert_eq!(law.control(&[], &[f32::NAN], &mut u), Err(Error::NonFinite));
        assert!(law.control(&[], &[-0.5, 1.0], &mut u).is_err());
        law.control(&[], &[-0.5], &mut u).unwrap();
        assert_eq!(u, [0.5]);
        law.control(&[], &[3.0], &mut u).unwrap();
        assert_eq!((u, law.outside()), ([0.0], 1));
    }
}
