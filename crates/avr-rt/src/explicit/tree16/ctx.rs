//! The assembly walk's context block at the start of the law's scratch:
//! its size, its type (AVR only; unused bytes elsewhere) and its constant
//! fields from the table.

use super::table::Tree16;
use crate::progmem::TableRead;

/// Bytes of the assembly walk's context at the start of `Scratch`.
pub(super) const CTX_BYTES: usize = 43;
#[cfg(target_arch = "avr")]
const _: () = assert!(CTX_BYTES == super::walk_avr::THETA_AT);

/// The assembly walk's context ([`super::walk_avr`], AVR only) at the start
/// of `Scratch`; elsewhere as many unused bytes.
#[cfg(target_arch = "avr")]
pub(super) type CtxBlock = super::walk_avr::Ctx;
/// The assembly walk's context (AVR only) at the start of `Scratch`;
/// here as many unused bytes.
#[cfg(not(target_arch = "avr"))]
pub(super) type CtxBlock = [u8; CTX_BYTES];

/// The assembly walk's context with the table's constant fields (flash
/// addresses, counts); the pointers, the stamp and the output shift are
/// set per call (`Empc16Law::walk_asm`).
#[cfg(target_arch = "avr")]
pub(super) fn ctx_block<T: TableRead>(tree: &Tree16<T>, at: &[u32; 4], row_bytes: u16) -> CtxBlock {
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
pub(super) fn ctx_block<T: TableRead>(_: &Tree16<T>, _: &[u32; 4], _: u16) -> CtxBlock {
    [0; CTX_BYTES]
}
