//! The per-set kernel's pass routines (`sets_avr` on the AVR, their
//! portable twins elsewhere) on caller-given records, for the tests that
//! run them on the ATmega2560 in simavr and compare every result with the
//! host's bit for bit (`tests/qp16_saturation.rs`: crafted records that
//! reach every saturation branch). The solver itself calls the same
//! dispatchers on its own records.
//!
//! ```
//! use kestrel_avr_rt::qp16::probe::{PassVar, members};
//! // One member on its lower bound: the residual unc - lo saturates.
//! let v = PassVar { unc: i32::MAX, lo: -1, pos: 1, ..PassVar::default() };
//! assert_eq!(members(&[v]), (1, 1, [i32::MAX]));
//! ```

use super::sets;

/// One variable's record as the pass routines see it: the per-set
/// solver's own record type (same layout, same meaning).
pub use super::sets::Var as PassVar;

/// The members' residuals `unc - (code bit 0 ? hi : lo)` (saturated) in
/// increasing variable order: `(mask, count, residuals)` (entries past the
/// count 0). `1 <= N <= 8` runs the AVR routine on the AVR.
pub fn members<const N: usize>(var: &[PassVar; N]) -> (usize, usize, [i32; N]) {
    let mut r = [0; N];
    let (mask, q) = sets::members(var, &mut r);
    (mask, q, r)
}

/// Each member's multiplier from `out` (in increasing variable order) into
/// its `star`; returns the mask of the members with `code < 2` whose
/// multiplier, negated (saturated) for a lower bound, is below `limit`.
pub fn stars<const N: usize>(var: &mut [PassVar; N], out: &[i32; N], limit: i32) -> u32 {
    sets::stars(var, out, limit)
}

/// The point and the most violated bound for `tol >= 0` (`out[k..]` the
/// inactive variables' `W_A r`): every record's `w`, the members' `nu =
/// star`, and `(index, code)` of the first strictly largest violation
/// above `tol` (index `N` for none).
pub fn scan<const N: usize>(
    var: &mut [PassVar; N],
    out: &[i32; N],
    k: usize,
    tol: i32,
) -> (usize, u8) {
    sets::scan(var, out, k, tol)
}
