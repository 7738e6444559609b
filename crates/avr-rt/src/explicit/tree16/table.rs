//! [`Tree16`]: the table read through [`TableRead`], its rows' values
//! (the Rust form of the assembly walk's row) and the one-time check of a
//! narrow table's indices.

use super::layout::{LEAF, NONE, Tree16Layout};
use crate::progmem::TableRead;
use kestrel_core::Error;

/// A [`Tree16Layout`] table read through [`TableRead`] (a
/// [`crate::progmem::FarTable`] in flash on the AVR, a byte slice on the host).
#[derive(Clone, Copy, Debug)]
pub struct Tree16<T> {
    pub(super) table: T,
    pub(super) layout: Tree16Layout,
}

impl<T: TableRead> Tree16<T> {
    /// The accessor; [`Error::DimensionMismatch`] if the table's length is
    /// not the layout's, [`Error::InvalidArgument`] for a layout whose
    /// offsets do not fit in `u32` ([`Tree16Layout::checked_offsets`]),
    /// more than 255 rows (65534 wide) or a scale above 30.
    pub fn new(table: T, layout: Tree16Layout) -> Result<Self, Error> {
        let Some([.., want]) = layout.checked_offsets() else {
            return Err(Error::InvalidArgument(
                "a layout whose sizes overflow 32 bits",
            ));
        };
        let len = table.len_bytes();
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
    pub(super) fn param(&self, j: usize) -> Option<(i8, i16, i16)> {
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
/// otherwise); the Rust form of the assembly walk's row (`walk_avr`).
#[inline]
pub(super) fn row_value<T: TableRead, const P: usize>(
    table: &T,
    at: u32,
    theta: &[i16; P],
) -> Option<i32> {
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
pub(super) fn read_bytes<T: TableRead, const N: usize>(table: &T, at: u32) -> Option<[u8; N]> {
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
pub(super) fn validate_narrow<T: TableRead>(tree: &Tree16<T>) -> Option<()> {
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
