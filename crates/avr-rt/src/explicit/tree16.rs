//! The firmware's fast explicit MPC: kestrel-empc's search tree with its
//! affine rows quantised to 16 bits, evaluated on the AVR's hardware
//! multiplier with the rows read straight from flash (`ELPM Z+`).
//!
//! What makes it fast (against [`super::FlashTree`]'s generic walk):
//!
//! - `theta` is quantised once per period to `i16` (parameter `j` with its
//!   own binary point, so its box fills 16 bits) and projected onto the box;
//! - every affine row (laws, output bounds; the tree's hyperplanes are
//!   differences of two of them) holds `i16` gains in one common scale
//!   `2^K` of the output and an `i32` constant, and is evaluated by one
//!   assembly kernel (four hardware `MUL`s per term, a 32-bit accumulator;
//!   the design proves the sum cannot overflow on the box);
//! - a row is evaluated at most once per period (a value cache in RAM,
//!   stamped with the period), so a node comparing "output i's law" with
//!   "its bound" costs two cached reads after the first time, and the
//!   leaf's law rows usually come for free;
//! - rows store only their columns from the first non-zero one (the
//!   tricopter's output bounds depend on the throttle alone: one term).
//!
//! Byte layout ([`Tree16Layout`], little-endian), in this order:
//! - parameters, 5 bytes each: the right shift `s` (`i8`) from Q15.16 to the
//!   parameter's `i16` units, the box `lb`, `ub` (`i16`, in those units);
//! - nodes in preorder, 5 bytes each: rows `a`, `b` (`u8`, `b` = [`NONE`]
//!   for zero), the child if `a <= b` (`u8`: [`NONE`] for the next node,
//!   otherwise a law index), the other child (`u16`: [`LEAF`] `|` law, or a
//!   node index);
//! - laws, `NU` row indices (`u8`) each;
//! - output bounds, rows of the lower and upper bound (`u8`, [`NONE`]: none);
//! - rows, [`Tree16Layout::row_bytes`] each: first column `start` (`u8`),
//!   constant (`i32`), gains (`i16`) of columns `start..P`, then zeros.
//!
//! `explicit::quantize` (design time) writes the table from
//! kestrel-empc's tree and checks it against the f64 evaluation.
//!
//! ```
//! use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16, Tree16Layout, LEAF, NONE};
//! use kestrel_core::ControlLaw;
//! // One parameter theta in [-1, 1] (Q15.16 >> 1: 2^15 units per 1),
//! // one output: z = -theta for theta <= 0, 0 otherwise, in units of 2^-16.
//! let layout = Tree16Layout { n_params: 1, n_outputs: 1, n_nodes: 1, n_laws: 2, n_rows: 3, root: 0, scale: 16, wide: false };
//! let mut b = vec![1u8];
//! b.extend((-32767i16).to_le_bytes());
//! b.extend(32767i16.to_le_bytes());
//! b.extend([2, NONE, 0]);                // theta <= 0: law 0
//! b.extend((LEAF | 1).to_le_bytes());    // otherwise law 1
//! b.extend([0, 1, NONE, NONE]);          // laws (rows 0, 1), no output bounds
//! for (c0, g) in [(0i32, -2i16), (0, 0), (0, 2)] { // -theta, 0, theta
//!     b.push(0);
//!     b.extend(c0.to_le_bytes());
//!     b.extend(g.to_le_bytes());
//! }
//! let tree = Tree16::new(&b[..], layout).unwrap();
//! let mut law = Empc16Law::<f32, _, 1, 1, 3>::new(tree, 0).unwrap();
//! let mut u = [0.0f32];
//! law.control(&[], &[-0.5], &mut u).unwrap();
//! assert_eq!(u, [0.5]);
//! law.control(&[], &[0.25], &mut u).unwrap();
//! assert_eq!(u, [0.0]);
//! ```

use crate::law::LawInfo;
use crate::output::RtScalar;
use crate::progmem::TableRead;
use crate::shift::round_shift32;
use kestrel_core::{ControlLaw, Error};

/// Marks a child code as a leaf (the low 15 bits are the law index).
pub const LEAF: u16 = 0x8000;
/// "None" in a `u8` field: no row `b` (zero), the next node, no bound.
pub const NONE: u8 = 0xFF;
/// "None" in a `u16` field of the wide layout ([`Tree16Layout::wide`]).
pub const NONE16: u16 = 0xFFFF;

/// Counts and scale of a [`Tree16`] table (the generated constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tree16Layout {
    /// Parameters `P`.
    pub n_params: usize,
    /// Outputs `NU`.
    pub n_outputs: usize,
    /// Tree nodes.
    pub n_nodes: usize,
    /// Laws.
    pub n_laws: usize,
    /// Affine rows (at most 255 in the narrow layout, 65534 in the wide).
    pub n_rows: usize,
    /// The root child code (node 0, or a leaf).
    pub root: u16,
    /// Fraction bits `K` of every row's value (value = row / 2^K).
    pub scale: u8,
    /// The wide layout: row and law indices are `u16` ([`NONE16`] for
    /// none; nodes of 8 bytes: `a`, `b`, the `a <= b` child, the other
    /// child), for trees beyond 255 rows or laws (Ns = 2). The narrow one
    /// (`u8` indices, 5-byte nodes) is what the assembly walk reads.
    pub wide: bool,
}

impl Tree16Layout {
    /// Bytes per parameter entry.
    pub const PARAM_BYTES: usize = 5;
    /// Bytes per node of the narrow layout.
    pub const NODE_BYTES: usize = 5;
    /// Bytes per node: 5 narrow, 8 wide.
    pub const fn node_bytes(&self) -> usize {
        if self.wide { 8 } else { Self::NODE_BYTES }
    }
    /// Bytes per row or law index: 1 narrow, 2 wide.
    pub const fn index_bytes(&self) -> usize {
        if self.wide { 2 } else { 1 }
    }
    /// Bytes per row: `start`, the constant, `P` gains.
    pub const fn row_bytes(&self) -> usize {
        5 + 2 * self.n_params
    }
    /// Byte offset of the nodes.
    pub const fn nodes_at(&self) -> usize {
        Self::PARAM_BYTES * self.n_params
    }
    /// Byte offset of the laws.
    pub const fn laws_at(&self) -> usize {
        self.nodes_at() + self.node_bytes() * self.n_nodes
    }
    /// Byte offset of the output bounds.
    pub const fn bounds_at(&self) -> usize {
        self.laws_at() + self.index_bytes() * self.n_laws * self.n_outputs
    }
    /// Byte offset of the rows.
    pub const fn rows_at(&self) -> usize {
        self.bounds_at() + 2 * self.index_bytes() * self.n_outputs
    }
    /// Total bytes.
    pub const fn bytes(&self) -> usize {
        self.rows_at() + self.n_rows * self.row_bytes()
    }
    /// The byte offsets of the nodes, laws, bounds and rows and the total
    /// bytes, computed in `u32`: the run-time's figures, since a wide table
    /// may pass 64 KiB, where the AVR's 16-bit `usize` (and so
    /// [`Tree16Layout::bytes`] there) would overflow.
    pub const fn offsets(&self) -> [u32; 5] {
        let nodes = (Self::PARAM_BYTES as u32) * (self.n_params as u32);
        let laws = nodes + (self.node_bytes() as u32) * (self.n_nodes as u32);
        let bounds =
            laws + (self.index_bytes() as u32) * (self.n_laws as u32) * (self.n_outputs as u32);
        let rows = bounds + 2 * (self.index_bytes() as u32) * (self.n_outputs as u32);
        let total = rows + (self.n_rows as u32) * (self.row_bytes() as u32);
        [nodes, laws, bounds, rows, total]
    }
}

/// A [`Tree16Layout`] table read through [`TableRead`] (a
/// [`crate::progmem::FarTable`] in flash on the AVR, a byte slice on the host).
#[derive(Clone, Copy, Debug)]
pub struct Tree16<T> {
    table: T,
    layout: Tree16Layout,
}

impl<T: TableRead> Tree16<T> {
    /// The accessor; [`Error::DimensionMismatch`] if the table's length is
    /// not the layout's, [`Error::InvalidArgument`] for more than 255 rows
    /// (65534 wide) or a scale above 30.
    pub fn new(table: T, layout: Tree16Layout) -> Result<Self, Error> {
        let (len, want) = (table.len_bytes(), layout.offsets()[4]);
        if len != want {
            let size = |v: u32| usize::try_from(v).unwrap_or(usize::MAX);
            return Err(Error::DimensionMismatch {
                expected: size(want),
                found: size(len),
            });
        }
        if layout.n_rows > if layout.wide { 65534 } else { 255 } {
            return Err(Error::InvalidArgument(
                "more rows than the layout's indices hold",
            ));
        }
        if layout.scale > 30 {
            return Err(Error::InvalidArgument("row scale above 2^30"));
        }
        Ok(Tree16 { table, layout })
    }
    /// The layout.
    pub fn layout(&self) -> &Tree16Layout {
        &self.layout
    }
    /// The table.
    pub fn table(&self) -> &T {
        &self.table
    }
    /// Parameter `j`: shift from Q15.16, box `lb`, `ub`.
    fn param(&self, j: usize) -> Option<(i8, i16, i16)> {
        let b: [u8; 5] = self
            .table
            .read_array((Tree16Layout::PARAM_BYTES * j) as u32)?;
        Some((
            b[0] as i8,
            i16::from_le_bytes([b[1], b[2]]),
            i16::from_le_bytes([b[3], b[4]]),
        ))
    }
}

/// `c0 + sum_{j >= start} c_j theta_j` of the row at table offset `at`
/// (the caller has checked the row index, so the row is inside the table;
/// the design bounds the sum within `i32` on the box, and it wraps
/// otherwise); the Rust form of the assembly walk's row (`super::walk_avr`).
#[inline]
fn row_value<T: TableRead, const P: usize>(table: &T, at: u32, theta: &[i16; P]) -> Option<i32> {
    let head: [u8; 5] = table.read_array(at)?;
    let start = head[0] as usize;
    let mut acc = i32::from_le_bytes([head[1], head[2], head[3], head[4]]);
    for (k, th) in theta.iter().skip(start).enumerate() {
        let c = i16::from_le_bytes(table.read_array(at + 5 + 2 * k as u32)?);
        acc = acc.wrapping_add(c as i32 * *th as i32);
    }
    Some(acc)
}

/// `N` bytes at table offset `at` (the caller has checked the range): one
/// `ELPM Z+` each on the AVR for tables in flash.
#[inline(always)]
fn read_bytes<T: TableRead, const N: usize>(table: &T, at: u32) -> Option<[u8; N]> {
    #[cfg(target_arch = "avr")]
    if let Some(base) = table.flash_address() {
        let addr = base.wrapping_add(at);
        let mut out = [0u8; N];
        let mut z = addr as u16;
        // SAFETY: sets RAMPZ (read only by ELPM); the bytes are constant
        // flash inside the table; `ELPM Z+` carries into RAMPZ itself.
        unsafe {
            core::arch::asm!("out 0x3B, {hh}", hh = in(reg) (addr >> 16) as u8, options(nostack, preserves_flags));
        }
        for b in out.iter_mut() {
            // SAFETY: as above.
            unsafe {
                core::arch::asm!(
                    "elpm {b}, Z+",
                    b = out(reg) *b,
                    inout("Z") z,
                    options(nostack, preserves_flags, readonly),
                );
            }
        }
        return Some(out);
    }
    table.read_array(at)
}

/// Bytes of the assembly walk's context at the start of [`Scratch`].
const CTX_BYTES: usize = 43;
#[cfg(target_arch = "avr")]
const _: () = assert!(CTX_BYTES == super::walk_avr::THETA_AT);

/// The assembly walk's context ([`super::walk_avr`], AVR only) at the start
/// of [`Scratch`]; elsewhere as many unused bytes.
#[cfg(target_arch = "avr")]
type CtxBlock = super::walk_avr::Ctx;
/// The assembly walk's context (AVR only) at the start of [`Scratch`];
/// here as many unused bytes.
#[cfg(not(target_arch = "avr"))]
type CtxBlock = [u8; CTX_BYTES];

/// The law's RAM scratch, in the order the assembly walk addresses it:
/// its context, the quantised `theta` (`P` `i16`) directly followed by the row value
/// cache, 5 bytes per row (the period stamp, then the `i32` value); for
/// the wide layout the cache is direct-mapped (row `r` in entry
/// `r mod R`) and `tags` holds each entry's row.
#[repr(C)]
#[derive(Clone, Debug)]
struct Scratch<const P: usize, const R: usize> {
    /// The assembly walk's context (`walk_avr::Ctx`, AVR only), directly
    /// before `theta` so the routine reaches both from one pointer.
    #[cfg_attr(not(target_arch = "avr"), allow(dead_code))]
    ctx: CtxBlock,
    theta: [i16; P],
    cache: [[u8; 5]; R],
    tags: [u16; R],
}

/// The fast explicit MPC law (see the module docs): `P` parameters
/// (`theta = [x; r]`, the first `nx` the state), `NU` outputs (the input
/// moves), a value cache for up to `R` rows. Works in any
/// [`RtScalar`]: `theta` is taken as Q15.16 and the outputs are given back
/// from Q15.16.
///
/// On the AVR, with the table in flash, one assembly routine
/// (`explicit/walk_avr.rs`, AVR only) quantises `theta`, walks the tree and evaluates
/// the leaf's outputs; elsewhere the same steps run in Rust (the host
/// tests' reference: the firmware's results are compared with it bit for
/// bit in simavr).
#[derive(Clone, Debug)]
pub struct Empc16Law<S, T, const P: usize, const NU: usize, const R: usize> {
    tree: Tree16<T>,
    nx: usize,
    /// The parameters' shifts and boxes, read from the table once.
    params: [(i8, i16, i16); P],
    /// The same as the table's bytes (shift, `lb`, `ub`), for the assembly walk.
    #[cfg_attr(not(target_arch = "avr"), allow(dead_code))]
    param_bytes: [[u8; 5]; P],
    /// Table offsets of the nodes, laws, bounds and rows (from the layout).
    at: [u32; 4],
    row_bytes: u16,
    scratch: Scratch<P, R>,
    period: u8,
    /// The next cache entry [`Self::next_period`] clears.
    sweep: usize,
    steps: u16,
    outside: u32,
    _s: core::marker::PhantomData<S>,
}

/// The evaluation of the tree at a quantised `theta`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Raw<const NU: usize> {
    /// The outputs in units of `2^-K` (the table's scale).
    pub z: [i32; NU],
    /// The leaf's law.
    pub law: u16,
    /// Tree nodes visited.
    pub steps: u16,
}

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize>
    Empc16Law<S, T, P, NU, R>
{
    /// The law over `tree`; [`Error::DimensionMismatch`] unless the table
    /// has `P` parameters, `NU` outputs, at most `R` rows (narrow layout;
    /// wide: `R` a power of two, the direct-mapped cache), and `nx < P`.
    pub fn new(tree: Tree16<T>, nx: usize) -> Result<Self, Error> {
        let l = tree.layout;
        for (expected, found) in [(P, l.n_params), (NU, l.n_outputs)] {
            if expected != found {
                return Err(Error::DimensionMismatch { expected, found });
            }
        }
        if (!l.wide && l.n_rows > R) || (l.wide && !R.is_power_of_two()) {
            return Err(Error::DimensionMismatch {
                expected: R,
                found: l.n_rows,
            });
        }
        if nx >= P {
            return Err(Error::DimensionMismatch {
                expected: P - 1,
                found: nx,
            });
        }
        let max_laws = if l.wide { usize::from(LEAF) } else { 255 };
        if P > 127 || NU > 255 || l.n_laws > max_laws || l.n_nodes > usize::from(LEAF) {
            return Err(Error::InvalidArgument(
                "more than 127 parameters, 255 outputs, the layout's laws, or 32768 nodes",
            ));
        }
        let mut params = [(0i8, 0i16, 0i16); P];
        let mut param_bytes = [[0u8; 5]; P];
        for (j, (pj, bj)) in params.iter_mut().zip(param_bytes.iter_mut()).enumerate() {
            *bj = tree
                .table
                .read_array((Tree16Layout::PARAM_BYTES * j) as u32)
                .ok_or(Error::OutOfRange)?;
            *pj = tree.param(j).ok_or(Error::OutOfRange)?;
            if pj.1 > pj.2 {
                return Err(Error::InvalidArgument("a parameter box with lb > ub"));
            }
            if !(0..=31).contains(&pj.0) {
                return Err(Error::InvalidArgument("a parameter shift outside 0..=31"));
            }
        }
        if !l.wide
            && (l.n_rows * l.row_bytes() > usize::from(u16::MAX)
                || Tree16Layout::NODE_BYTES * l.n_nodes > usize::from(u16::MAX))
        {
            return Err(Error::InvalidArgument("rows or nodes above 64 KiB"));
        }
        let [nodes_at, laws_at, bounds_at, rows_at, _] = l.offsets();
        let at = [nodes_at, laws_at, bounds_at, rows_at];
        if !l.wide {
            validate_narrow(&tree).ok_or(Error::OutOfRange)?;
        }
        let ctx = ctx_block(&tree, &at, l.row_bytes() as u16);
        Ok(Empc16Law {
            tree,
            nx,
            params,
            param_bytes,
            at,
            row_bytes: l.row_bytes() as u16,
            scratch: Scratch {
                ctx,
                theta: [0; P],
                cache: [[0; 5]; R],
                tags: [0; R],
            },
            period: 0,
            sweep: 0,
            steps: 0,
            outside: 0,
            _s: core::marker::PhantomData,
        })
    }
    /// Periods whose parameter was outside the box (projected onto it).
    pub fn outside(&self) -> u32 {
        self.outside
    }
    /// The tree.
    pub fn tree(&self) -> &Tree16<T> {
        &self.tree
    }

    /// `theta` in the table's `i16` units, projected onto the box; whether
    /// it was outside. [`Error::NonFinite`] for a non-finite entry.
    pub fn quantize(&self, theta: &[S; P]) -> Result<([i16; P], bool), Error> {
        let mut bits = [0i32; P];
        for (b, t) in bits.iter_mut().zip(theta) {
            *b = t.to_q16().ok_or(Error::NonFinite)?;
        }
        Ok(self.quantize_bits(&bits))
    }

    /// [`Empc16Law::quantize`] from the Q15.16 bits (the Rust form of the
    /// assembly's first part).
    fn quantize_bits(&self, bits: &[i32; P]) -> ([i16; P], bool) {
        let mut q = [0i16; P];
        let mut outside = false;
        for ((qj, &b), &(s, lb, ub)) in q.iter_mut().zip(bits).zip(&self.params) {
            // `new` checked 0 <= s <= 31.
            let v = round_shift32(b, s as u8);
            *qj = if v < lb as i32 {
                outside = true;
                lb
            } else if v > ub as i32 {
                outside = true;
                ub
            } else {
                v as i16
            };
        }
        (q, outside)
    }

    /// The right shift from Q15.16 to parameter `j`'s `i16` units (0 for
    /// `j >= P`).
    pub fn param_shift(&self, j: usize) -> u8 {
        self.params.get(j).map_or(0, |p| p.0 as u8)
    }

    /// A pseudo-random quantised parameter in the box (a 32-bit LCG in
    /// `seed`, the same sequence on every target): what the firmware's
    /// on-target check evaluates and the host compares bit for bit.
    pub fn box_sample(&self, seed: &mut u32) -> [i16; P] {
        let mut q = [0i16; P];
        for (qj, &(_, lb, ub)) in q.iter_mut().zip(&self.params) {
            *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let span = (i32::from(ub) - i32::from(lb)) as u32 + 1; // new: lb <= ub
            let r = ((*seed >> 16) * span) >> 16; // < span
            *qj = (i32::from(lb) + r as i32) as i16;
        }
        q
    }

    /// The whole law's parameter of the on-target check's sample `i` as
    /// Q15.16 bits (test instrumentation, the same on every target):
    /// `q` (from [`Self::box_sample`]) scaled back, for odd `i` moved off
    /// the quantisation grid by up to a unit either way (the rounding),
    /// and for every fourth `i` one parameter moved beyond its box by
    /// 2^12 units (the projection).
    #[doc(hidden)]
    pub fn check_bits(&self, q: &[i16; P], i: u16) -> [i32; P] {
        let mut bits = [0i32; P];
        for (j, (b, (&qj, &(s, _, _)))) in
            bits.iter_mut().zip(q.iter().zip(&self.params)).enumerate()
        {
            // 2^s by multiplication (s <= 16): no variable shift.
            let unit = 2i32.pow(u32::from((s as u8).min(16)));
            *b = i32::from(qj) * unit;
            let h = u32::from(i)
                .wrapping_mul(9)
                .wrapping_add(j as u32)
                .wrapping_mul(2_654_435_761);
            if i % 2 == 1 {
                // An offset in [-2^s, 2^s).
                *b += ((h >> 8) as i32 & (2 * unit - 1)) - unit;
            }
            if i.is_multiple_of(4) && j == usize::from(i / 4) % P {
                let far = unit * 4096;
                *b += if h & 1 == 0 { far } else { -far };
            }
        }
        bits
    }

    /// The whole law's `f32` parameter of the on-target check's sample `i`
    /// (test instrumentation, the same on every target): the values of
    /// `bits` (from [`Self::check_bits`]) with up to the 8 low mantissa
    /// bits flipped (bits below Q15.16's resolution, where the rounding
    /// to Q15.16 happens; zero becomes a subnormal), and for every 16th
    /// `i` (`i % 16 == 5`) one value non-finite (a NaN or an infinity).
    #[doc(hidden)]
    pub fn check_f32(&self, bits: &[i32; P], i: u16) -> [f32; P] {
        let mut v = [0f32; P];
        for (j, (vj, &b)) in v.iter_mut().zip(bits).enumerate() {
            let h = u32::from(i)
                .wrapping_mul(9)
                .wrapping_add(j as u32)
                .wrapping_mul(2_246_822_519);
            let f = <f32 as RtScalar>::from_q16(b);
            let mut v = f.to_bits() ^ ((h >> 20) & 0xFF);
            if i % 16 == 5 && j == usize::from(i / 16) % P {
                // The exponent all ones: an infinity (mantissa 0) or a
                // NaN, either sign.
                v = (v & 0x8000_0000) | 0x7F80_0000 | (h & 0x40_0000);
            }
            *vj = f32::from_bits(v);
        }
        v
    }

    /// Rows evaluated in the current period (test instrumentation).
    #[doc(hidden)]
    pub fn rows_evaluated(&self) -> usize {
        self.scratch
            .cache
            .iter()
            .filter(|e| e[0] == self.period)
            .count()
    }

    /// A new period stamp for the value cache (1 to 255: 0 is never used,
    /// so a fresh cache is empty). A stamp comes back after 255 periods:
    /// each period clears `ceil(R / 255)` entries in turn, so every entry
    /// is cleared within 255 periods of its writing and an old value is
    /// never taken for this period's (the same work every period, instead
    /// of clearing the whole cache when the stamp wraps).
    fn next_period(&mut self) {
        self.period = self.period.wrapping_add(1);
        if self.period == 0 {
            self.period = 1;
        }
        for _ in 0..R.div_ceil(255) {
            if let Some(e) = self.scratch.cache.get_mut(self.sweep) {
                e[0] = 0;
            }
            self.sweep = if self.sweep + 1 >= R {
                0
            } else {
                self.sweep + 1
            };
        }
    }

    /// The value of row `r` at the scratch's `theta` (cached for the
    /// period); `None` for a row outside the table.
    fn value(&mut self, r: u16) -> Option<i32> {
        let l = &self.tree.layout;
        if r as usize >= l.n_rows {
            return None;
        }
        let wide = l.wide;
        // Narrow: `new` checked n_rows <= R; wide: R is a power of two.
        let i = if wide {
            r as usize & (R - 1)
        } else {
            r as usize
        };
        let period = self.period;
        let e = self.scratch.cache.get(i)?;
        if e[0] == period && (!wide || self.scratch.tags.get(i) == Some(&r)) {
            return Some(i32::from_le_bytes([e[1], e[2], e[3], e[4]]));
        }
        let at = if wide {
            self.at[3] + u32::from(r) * u32::from(self.row_bytes)
        } else {
            // `new` checked that every row's offset fits in 16 bits: a
            // 16-bit product (no 32-bit multiply call on the AVR).
            self.at[3] + u32::from(r.wrapping_mul(self.row_bytes))
        };
        let v = row_value(&self.tree.table, at, &self.scratch.theta)?;
        let b = v.to_le_bytes();
        *self.scratch.cache.get_mut(i)? = [period, b[0], b[1], b[2], b[3]];
        if let Some(t) = self.scratch.tags.get_mut(i) {
            *t = r;
        }
        Some(v)
    }

    /// Node `code`: rows `a`, `b`, the `a <= b` child and the other child
    /// as `u16` ([`NONE16`] for none), from either layout.
    fn node(&self, code: u16) -> Option<[u16; 4]> {
        if self.tree.layout.wide {
            let n: [u8; 8] = read_bytes(&self.tree.table, self.at[0] + 8 * u32::from(code))?;
            Some([
                u16::from_le_bytes([n[0], n[1]]),
                u16::from_le_bytes([n[2], n[3]]),
                u16::from_le_bytes([n[4], n[5]]),
                u16::from_le_bytes([n[6], n[7]]),
            ])
        } else {
            // `new` checked that the nodes fit in 64 KiB: a 16-bit product.
            let n: [u8; 5] = read_bytes(
                &self.tree.table,
                self.at[0] + u32::from(code.wrapping_mul(5)),
            )?;
            let w = |b: u8| if b == NONE { NONE16 } else { u16::from(b) };
            Some([w(n[0]), w(n[1]), w(n[2]), u16::from_le_bytes([n[3], n[4]])])
        }
    }

    /// Index `k` (a row or law index, [`NONE16`] for none) of the index
    /// array at table offset `at`, in the layout's width.
    fn index(&self, at: u32, k: u32) -> Option<u16> {
        if self.tree.layout.wide {
            read_bytes::<_, 2>(&self.tree.table, at + 2 * k).map(u16::from_le_bytes)
        } else {
            read_bytes::<_, 1>(&self.tree.table, at + k)
                .map(|[b]| if b == NONE { NONE16 } else { u16::from(b) })
        }
    }

    /// Evaluates the tree at a quantised `theta` (in the box): the outputs
    /// in units of `2^-K`, the law, and the nodes visited.
    /// [`Error::OutOfRange`] for a corrupted table (a row, law or node
    /// index out of range, a right child that does not come after its node).
    pub fn evaluate_raw(&mut self, theta: &[i16; P]) -> Result<Raw<NU>, Error> {
        self.scratch.theta = *theta;
        self.next_period();
        #[cfg(target_arch = "avr")]
        if let Some(r) = self.walk_asm(None, 0) {
            return r;
        }
        self.walk().ok_or(Error::OutOfRange)
    }

    /// The walk at the scratch's `theta` in Rust (the period is set).
    fn walk(&mut self) -> Option<Raw<NU>> {
        let mut code = self.tree.layout.root;
        let mut steps: u16 = 0;
        let limit = self.tree.layout.n_nodes;
        while code & LEAF == 0 {
            if code as usize >= limit {
                return None;
            }
            let [ra, rb, left, right] = self.node(code)?;
            steps = steps.saturating_add(1);
            let a = self.value(ra)?;
            let b = if rb == NONE16 { 0 } else { self.value(rb)? };
            code = if a <= b {
                if left == NONE16 {
                    code + 1
                } else {
                    LEAF | (left & !LEAF)
                }
            } else {
                // Children come after their node (preorder): the walk ends.
                if right & LEAF == 0 && right <= code {
                    return None;
                }
                right
            };
        }
        let law = code & !LEAF;
        if law as usize >= self.tree.layout.n_laws {
            return None;
        }
        let mut z = [0i32; NU];
        for (o, zo) in z.iter_mut().enumerate() {
            let r = self.index(self.at[1], (NU * law as usize + o) as u32)?;
            let lo = self.index(self.at[2], 2 * o as u32)?;
            let hi = self.index(self.at[2], 2 * o as u32 + 1)?;
            let lo = if lo != NONE16 {
                Some(self.value(lo)?)
            } else {
                None
            };
            let hi = if hi != NONE16 {
                Some(self.value(hi)?)
            } else {
                None
            };
            let mut v = self.value(r)?;
            if let Some(lo) = lo {
                v = v.max(lo);
            }
            if let Some(hi) = hi {
                v = v.min(hi);
            }
            *zo = v;
        }
        Some(Raw { z, law, steps })
    }

    /// The assembly walk (`explicit/walk_avr.rs`, AVR only) when the table is in flash:
    /// with `bits`, `theta` is quantised from those Q15.16 values first
    /// (the outside flag is returned through `self.outside`); the outputs
    /// rounded and shifted right by `out_shift` bits; `None`: the table is
    /// not in flash.
    #[cfg(target_arch = "avr")]
    #[inline(always)]
    fn walk_asm(
        &mut self,
        bits: Option<&[i32; P]>,
        out_shift: u8,
    ) -> Option<Result<Raw<NU>, Error>> {
        let mut z = [0i32; NU];
        let status = self.run_asm(bits.map(|b| (&b[..], &[][..])), false, out_shift, &mut z)?;
        Some(if status == 0 {
            Ok(Raw {
                z,
                law: u16::from(self.scratch.ctx.law),
                steps: self.scratch.ctx.steps,
            })
        } else {
            Err(Error::OutOfRange)
        })
    }

    /// One call of the assembly routine (`explicit/walk_avr.rs`) with the
    /// outputs into `z`: its status (0; 2 for a non-finite `f32` value),
    /// the outside count updated; `None`: the table is not in flash or
    /// wide. `bits` are Q15.16 values, or with `f32_theta` `f32` bit
    /// patterns.
    #[cfg(target_arch = "avr")]
    #[inline(always)]
    fn run_asm(
        &mut self,
        bits: Option<(&[i32], &[i32])>,
        f32_theta: bool,
        out_shift: u8,
        z: &mut [i32; NU],
    ) -> Option<u8> {
        if self.tree.layout.wide {
            return None; // the assembly reads the narrow layout
        }
        self.tree.table.flash_address()?;
        // The context's constant fields were written by `new` (`ctx_block`);
        // the pointers (the law may have moved since), the stamp and the
        // output shift are this call's.
        let cache = self.scratch.cache.as_mut_ptr() as usize as u16;
        let params = self.param_bytes.as_ptr() as usize as u16;
        let ctx = &mut self.scratch.ctx;
        ctx.cache = cache;
        // The P values: q16's first nx, then q16b's (the caller checked
        // that the two hold P).
        let (first, rest) = bits.unwrap_or((&[], &[]));
        ctx.q16 = if bits.is_some() {
            first.as_ptr() as usize as u16
        } else {
            0
        };
        ctx.q16b = rest.as_ptr() as usize as u16;
        ctx.nx = first.len() as u8;
        ctx.params = params;
        ctx.out = z.as_mut_ptr() as usize as u16;
        ctx.period = self.period;
        ctx.out_shift = out_shift;
        ctx.f32_theta = u8::from(f32_theta);
        // SAFETY: `ctx` is the start of this law's scratch (`repr(C)`: the
        // context, theta, then the cache) and points at its parameter
        // bytes, `z` (NU values) and the bits (P values in two slices); the routine
        // writes only the scratch (row indices checked against
        // `n_rows <= R`), `z` and the context, and reads flash inside the
        // table (indices checked).
        let status = unsafe { super::walk_avr::kestrel_empc16_eval(ctx) };
        if self.scratch.ctx.outside != 0 {
            self.outside = self.outside.saturating_add(1);
        }
        Some(status)
    }
}

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize> ControlLaw
    for Empc16Law<S, T, P, NU, R>
{
    type Scalar = S;
    crate::law::parametric_law_sizes!();
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        for (found, expected) in [(x.len(), self.nx), (r.len(), P - self.nx), (u.len(), NU)] {
            if found != expected {
                return Err(Error::DimensionMismatch { expected, found });
            }
        }
        self.solve(x, r, u)
    }
}

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize>
    Empc16Law<S, T, P, NU, R>
{
    /// One period from `theta = [x; r]` (checked lengths) in one frame of
    /// its own (conversion to Q15.16, quantisation, walk, outputs): inlined
    /// into the caller's large frame, every local costs a long
    /// stack-pointer adjustment on the AVR.
    #[inline(never)]
    fn solve(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        self.next_period();
        // Scalars stored as Q15.16 bits: the routine reads them in place;
        // f32: the routine reads their bits in place and converts them
        // itself (exactly as `to_q16`), no Q15.16 copy.
        #[cfg(target_arch = "avr")]
        if let (Some(xb), Some(rb)) = (S::as_q16_bits(x), S::as_q16_bits(r)) {
            if let Some(res) = self.solve_asm((xb, rb), false, u) {
                return res;
            }
        } else if let (Some(xb), Some(rb)) = (S::as_f32_bits(x), S::as_f32_bits(r)) {
            if let Some(res) = self.solve_asm((xb, rb), true, u) {
                return res;
            }
        }
        // theta = [x; r] as Q15.16 bits, in one pass.
        let mut bits = [0i32; P];
        for (b, t) in bits.iter_mut().zip(x.iter().chain(r)) {
            *b = t.to_q16().ok_or(Error::NonFinite)?;
        }
        // On the AVR with the table in flash: quantisation, walk and the
        // outputs in Q15.16 (scale >= 16) in one assembly routine.
        #[cfg(target_arch = "avr")]
        if let Some(r) = self.solve_asm((&bits[..], &[]), false, u) {
            return r;
        }
        self.solve_rust(&bits, u)
    }

    /// [`Self::solve`] on the AVR's assembly routine (`None`: the table is
    /// not in flash, wide, or has a scale below 16).
    #[cfg(target_arch = "avr")]
    #[inline(always)]
    fn solve_asm(
        &mut self,
        bits: (&[i32], &[i32]),
        f32_theta: bool,
        u: &mut [S],
    ) -> Option<Result<(), Error>> {
        let k = self.tree.layout.scale;
        if k < 16 {
            return None;
        }
        let mut z = [0i32; NU];
        let status = self.run_asm(Some(bits), f32_theta, k - 16, &mut z)?;
        match status {
            0 => {}
            2 => return Some(Err(Error::NonFinite)),
            _ => return Some(Err(Error::OutOfRange)),
        }
        self.steps = self.scratch.ctx.steps;
        for (ui, zi) in u.iter_mut().zip(z) {
            *ui = S::from_q16(zi);
        }
        Some(Ok(()))
    }

    /// [`Self::solve`] in Rust (the host's path, and tables not in flash).
    #[inline(never)]
    fn solve_rust(&mut self, bits: &[i32; P], u: &mut [S]) -> Result<(), Error> {
        let k = self.tree.layout.scale;
        let (q, outside) = self.quantize_bits(bits);
        self.scratch.theta = q;
        if outside {
            self.outside = self.outside.saturating_add(1);
        }
        let raw = self.walk().ok_or(Error::OutOfRange)?;
        self.steps = raw.steps;
        if k >= 16 {
            let s = k - 16;
            for (ui, zi) in u.iter_mut().zip(raw.z) {
                *ui = S::from_q16(round_shift32(zi, s));
            }
        } else {
            outputs_up(&raw.z, 16 - k, u);
        }
        Ok(())
    }
}

/// Checks every index of a narrow table once (the assembly walk relies on
/// it and reads them unchecked): the root; every node's rows (`b` may be
/// [`NONE`]), its `a <= b` child (a law, or [`NONE`] for the next node,
/// which must exist), its other child (a law, or a node after it); every
/// law's rows; the output bounds' rows (or [`NONE`]). `None` for any index
/// out of range (or a table read outside the table): then no walk can
/// leave the table or loop.
///
/// Never inlined: inlined into the firmware's large `main` frame, the
/// compiler's 24-bit flash address sums (`FarTable` reads) took the carry
/// into `RAMPZ` the wrong way (an `SBCI` after the frame pointer's SREG
/// save and restore), so a table straddling 64 kB was read at `RAMPZ`
/// 0xFF and crashed simavr (seen in the f32 `empc-check` firmware; in a
/// frame of its own the sums are plain `ADD`/`ADC`).
#[inline(never)]
fn validate_narrow<T: TableRead>(tree: &Tree16<T>) -> Option<()> {
    let l = &tree.layout;
    let [nodes_at, laws_at, bounds_at, _, _] = l.offsets();
    let row = |r: u8| usize::from(r) < l.n_rows;
    let law = |c: u16| usize::from(c & !LEAF) < l.n_laws;
    let ok = |c: bool| c.then_some(());
    ok(if l.root & LEAF != 0 {
        law(l.root)
    } else {
        usize::from(l.root) < l.n_nodes
    })?;
    for code in 0..l.n_nodes {
        let n: [u8; 5] = tree
            .table
            .read_array(nodes_at + (Tree16Layout::NODE_BYTES * code) as u32)?;
        ok(row(n[0]) && (n[1] == NONE || row(n[1])))?;
        ok(if n[2] == NONE {
            code + 1 < l.n_nodes
        } else {
            law(u16::from(n[2]))
        })?;
        let right = u16::from_le_bytes([n[3], n[4]]);
        ok(if right & LEAF != 0 {
            law(right)
        } else {
            code < usize::from(right) && usize::from(right) < l.n_nodes
        })?;
    }
    for k in 0..l.n_laws * l.n_outputs {
        let [r]: [u8; 1] = tree.table.read_array(laws_at + k as u32)?;
        ok(row(r))?;
    }
    for k in 0..2 * l.n_outputs {
        let [r]: [u8; 1] = tree.table.read_array(bounds_at + k as u32)?;
        ok(r == NONE || row(r))?;
    }
    Some(())
}

/// The assembly walk's context with the table's constant fields (flash
/// addresses, counts); the pointers, the stamp and the output shift are
/// set per call (`Empc16Law::walk_asm`).
#[cfg(target_arch = "avr")]
fn ctx_block<T: TableRead>(tree: &Tree16<T>, at: &[u32; 4], row_bytes: u16) -> CtxBlock {
    let base = tree.table.flash_address().unwrap_or(0);
    let addr = |off: u32| {
        let b = base.wrapping_add(off).to_le_bytes();
        [b[0], b[1], b[2], 0]
    };
    let l = &tree.layout;
    super::walk_avr::Ctx {
        nodes: addr(at[0]),
        rows: addr(at[3]),
        laws: addr(at[1]),
        bounds: addr(at[2]),
        cache: 0,
        q16: 0,
        params: 0,
        out: 0,
        root: l.root,
        n_nodes: l.n_nodes as u16,
        n_rows: l.n_rows as u8,
        n_laws: l.n_laws as u8,
        np: l.n_params as u8,
        nu: l.n_outputs as u8,
        rb: row_bytes as u8,
        period: 0,
        steps: 0,
        outside: 0,
        law: 0,
        f32_theta: 0,
        out_shift: 0,
        q16b: 0,
        nx: 0,
    }
}

/// The assembly walk's context (AVR only): unused bytes here.
#[cfg(not(target_arch = "avr"))]
fn ctx_block<T: TableRead>(_: &Tree16<T>, _: &[u32; 4], _: u16) -> CtxBlock {
    [0; CTX_BYTES]
}

/// Outputs of a table with fewer than 16 fraction bits: `z 2^s`, saturated.
#[cold]
#[inline(never)]
fn outputs_up<S: RtScalar, const NU: usize>(z: &[i32; NU], s: u8, u: &mut [S]) {
    for (ui, &zi) in u.iter_mut().zip(z) {
        *ui = S::from_q16(zi.saturating_mul(1 << s.min(30)));
    }
}

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize> LawInfo
    for Empc16Law<S, T, P, NU, R>
{
    /// The tree nodes visited in the last period.
    fn iterations(&self) -> u16 {
        self.steps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One parameter theta in [-1, 1] (2^15 units per 1), one output:
    /// z = -theta for theta <= 0, 0 otherwise; output bounds [-0.25, 0.75]
    /// (rows 3, 4), scale 2^16.
    fn table() -> (Vec<u8>, Tree16Layout) {
        let layout = Tree16Layout {
            n_params: 1,
            n_outputs: 1,
            n_nodes: 1,
            n_laws: 2,
            n_rows: 5,
            root: 0,
            scale: 16,
            wide: false,
        };
        let mut b = vec![1u8];
        b.extend((-32767i16).to_le_bytes());
        b.extend(32767i16.to_le_bytes());
        b.extend([2, NONE, 0]);
        b.extend((LEAF | 1).to_le_bytes());
        b.extend([0, 1, 3, 4]);
        for (start, c0, g) in [
            (0u8, 0i32, -2i16),
            (1, 0, 0),
            (0, 0, 2),
            (1, -16384, 0),
            (1, 49152, 0),
        ] {
            b.push(start);
            b.extend(c0.to_le_bytes());
            b.extend(g.to_le_bytes());
        }
        assert_eq!(b.len(), layout.bytes());
        (b, layout)
    }

    fn law(b: &[u8], l: Tree16Layout) -> Empc16Law<f64, &[u8], 1, 1, 8> {
        Empc16Law::new(Tree16::new(b, l).unwrap(), 0).unwrap()
    }

    #[test]
    fn evaluates_the_tree_with_output_bounds_and_box() {
        let (b, l) = table();
        let mut law = law(&b, l);
        let mut u = [0.0];
        for (th, want, outside) in [
            (-0.5, 0.5, 0),
            (-0.9, 0.75, 0), // clamped by the upper bound row
            (0.3, 0.0, 0),
            (-3.0, 0.75, 1), // projected onto the box
        ] {
            law.control(&[], &[th], &mut u).unwrap();
            assert!((u[0] - want).abs() < 1e-4, "theta {th}: {} != {want}", u[0]);
            assert_eq!(law.outside(), outside);
        }
        assert_eq!(law.iterations(), 1);
    }

    #[test]
    fn the_value_cache_is_per_period() {
        // Many periods (the u8 stamp wraps) give the same answers as fresh
        // laws, with a cache swept one entry per period (R = 8) and two
        // (R = 300), and with the same parameter every period (each row
        // cached once and then only read: the sweep must clear it before
        // its stamp comes back).
        let (b, l) = table();
        let mut law = law(&b, l);
        let mut big: Empc16Law<f64, &[u8], 1, 1, 300> =
            Empc16Law::new(Tree16::new(&b[..], l).unwrap(), 0).unwrap();
        let mut same = self::law(&b, l);
        let mut u = [0.0];
        let mut w = [0.0];
        for k in 0..1200 {
            let th = ((k * 37) % 200) as f64 / 100.0 - 1.0;
            law.control(&[], &[th], &mut u).unwrap();
            big.control(&[], &[th], &mut w).unwrap();
            let mut fresh = self::law(&b, l);
            let mut v = [0.0];
            fresh.control(&[], &[th], &mut v).unwrap();
            assert_eq!(u, v, "period {k}");
            assert_eq!(w, v, "period {k}, R = 300");
            // Alternate two parameters in `same` after a long run at one.
            let th2 = if k < 600 { -0.5 } else { th };
            same.control(&[], &[th2], &mut u).unwrap();
            fresh.control(&[], &[th2], &mut v).unwrap();
            assert_eq!(u, v, "period {k}, held parameter");
        }
    }

    #[test]
    fn a_row_unused_for_255_periods_is_not_taken_from_the_cache() {
        // Period 1 caches law 0's row (theta < 0); 254 periods on the other
        // side leave it alone; period 256 has the stamp 1 again: the row
        // must be evaluated anew (the sweep cleared it), not read back.
        let (b, l) = table();
        let mut law = law(&b, l);
        let mut u = [0.0];
        law.control(&[], &[-0.5], &mut u).unwrap();
        assert!((u[0] - 0.5).abs() < 1e-4);
        for _ in 0..254 {
            law.control(&[], &[0.5], &mut u).unwrap();
            assert_eq!(u, [0.0]);
        }
        law.control(&[], &[-0.6], &mut u).unwrap();
        assert!((u[0] - 0.6).abs() < 1e-4, "{} (a stale 0.5?)", u[0]);
    }

    #[test]
    fn bad_tables_and_inputs_are_errors_not_panics() {
        let (b, l) = table();
        assert!(matches!(
            Tree16::new(&b[..b.len() - 1], l),
            Err(Error::DimensionMismatch { .. })
        ));
        let big = Tree16Layout { scale: 31, ..l };
        let mut bb = b.clone();
        bb.truncate(big.bytes());
        assert!(Tree16::new(&bb[..], big).is_err());
        let tree = Tree16::new(&b[..], l).unwrap();
        // Wrong dimensions, too small a cache, no reference.
        assert!(Empc16Law::<f64, _, 2, 1, 8>::new(tree, 0).is_err());
        assert!(Empc16Law::<f64, _, 1, 2, 8>::new(tree, 0).is_err());
        assert!(Empc16Law::<f64, _, 1, 1, 4>::new(tree, 0).is_err());
        assert!(Empc16Law::<f64, _, 1, 1, 8>::new(tree, 1).is_err());
        let mut law = law(&b, l);
        let mut u = [0.0];
        assert_eq!(law.control(&[], &[f64::NAN], &mut u), Err(Error::NonFinite));
        assert_eq!(
            law.control(&[], &[f64::INFINITY], &mut u),
            Err(Error::NonFinite)
        );
        assert!(law.control(&[], &[0.0, 1.0], &mut u).is_err());
        // A node pointing at a row past the table, a child past the nodes,
        // a law past the laws, a cycle.
        let node = l.nodes_at();
        for (at, v) in [(node, 9u8), (node + 3, 5), (node + 2, 7)] {
            let mut bad = b.clone();
            bad[at] = v;
            if at == node + 3 {
                bad[at + 1] = 0; // child node 5 of a 1-node tree
            }
            // Found by the check of every index when the law is made.
            assert_eq!(
                Empc16Law::<f64, _, 1, 1, 8>::new(Tree16::new(&bad[..], l).unwrap(), 0).err(),
                Some(Error::OutOfRange),
                "corrupted byte {at}"
            );
        }
        let mut cyc = b.clone();
        cyc[node + 3] = 0;
        cyc[node + 4] = 0; // theta > 0 loops back to node 0
        assert_eq!(
            Empc16Law::<f64, _, 1, 1, 8>::new(Tree16::new(&cyc[..], l).unwrap(), 0).err(),
            Some(Error::OutOfRange)
        );
        // A law's row and an output bound's row past the rows.
        for at in [l.laws_at(), l.bounds_at() + 1] {
            let mut bad = b.clone();
            bad[at] = 7;
            assert_eq!(
                Empc16Law::<f64, _, 1, 1, 8>::new(Tree16::new(&bad[..], l).unwrap(), 0).err(),
                Some(Error::OutOfRange),
                "corrupted byte {at}"
            );
        }
    }
}
