//! [`Empc16Law`]: the law's state (parameters, table offsets, the RAM
//! scratch with the row value cache) and its construction; the walk, the
//! assembly call and the period are in the sibling modules.

use super::ctx::{CtxBlock, ctx_block};
use super::layout::{LEAF, Tree16Layout};
use super::table::{Tree16, validate_narrow};
use crate::output::RtScalar;
use crate::progmem::TableRead;
use kestrel_core::Error;

/// The law's RAM scratch, in the order the assembly walk addresses it:
/// its context, the quantised `theta` (`P` `i16`) directly followed by the row value
/// cache, 5 bytes per row (the period stamp, then the `i32` value); for
/// the wide layout the cache is direct-mapped (row `r` in entry
/// `r mod R`) and `tags` holds each entry's row.
#[repr(C)]
#[derive(Clone, Debug)]
pub(super) struct Scratch<const P: usize, const R: usize> {
    /// The assembly walk's context (`walk_avr::Ctx`, AVR only), directly
    /// before `theta` so the routine reaches both from one pointer.
    #[cfg_attr(not(target_arch = "avr"), allow(dead_code))]
    pub(super) ctx: CtxBlock,
    pub(super) theta: [i16; P],
    pub(super) cache: [[u8; 5]; R],
    pub(super) tags: [u16; R],
}

/// The fast explicit MPC law (see the module docs): `P` parameters
/// (`theta = [x; r]`, the first `nx` the state), `NU` outputs (the input
/// moves), a value cache for up to `R` rows. Works in any
/// [`RtScalar`]: `theta` is taken as Q15.16 and the outputs are given back
/// from Q15.16.
///
/// On the AVR, with the table in flash, one assembly routine
/// (`explicit/tree16/walk_avr.rs`, AVR only) quantises `theta`, walks the tree and evaluates
/// the leaf's outputs; elsewhere the same steps run in Rust (the host
/// tests' reference: the firmware's results are compared with it bit for
/// bit in simavr).
#[derive(Clone, Debug)]
pub struct Empc16Law<S, T, const P: usize, const NU: usize, const R: usize> {
    pub(super) tree: Tree16<T>,
    pub(super) nx: usize,
    /// The parameters' shifts and boxes, read from the table once.
    pub(super) params: [(i8, i16, i16); P],
    /// The same as the table's bytes (shift, `lb`, `ub`), for the assembly walk.
    #[cfg_attr(not(target_arch = "avr"), allow(dead_code))]
    pub(super) param_bytes: [[u8; 5]; P],
    /// Table offsets of the nodes, laws, bounds and rows (from the layout).
    pub(super) at: [u32; 4],
    pub(super) row_bytes: u16,
    pub(super) scratch: Scratch<P, R>,
    pub(super) period: u8,
    /// The next cache entry [`Self::next_period`] clears.
    pub(super) sweep: usize,
    pub(super) steps: u16,
    pub(super) outside: u32,
    pub(super) _s: core::marker::PhantomData<S>,
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

    /// The right shift from Q15.16 to parameter `j`'s `i16` units (0 for
    /// `j >= P`).
    pub fn param_shift(&self, j: usize) -> u8 {
        self.params.get(j).map_or(0, |p| p.0 as u8)
    }
}
