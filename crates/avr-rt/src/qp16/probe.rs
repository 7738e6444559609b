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

use super::sets::{self, Var};

/// One variable's record as the pass routines see it (the fields of the
/// per-set solver's record, same meaning).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PassVar {
    /// The unconstrained solution `w_unc` (raw Q15.16).
    pub unc: i32,
    /// The lower bound.
    pub lo: i32,
    /// The upper bound.
    pub hi: i32,
    /// The point.
    pub w: i32,
    /// The pass's multiplier of this variable's bound (a member).
    pub star: i32,
    /// The entry position plus one, 0 when inactive.
    pub pos: u8,
    /// The member's side code: bit 0 upper, bit 1 equal bounds.
    pub code: u8,
    /// The current multiplier of its bound.
    pub nu: i32,
}

fn to_var(v: &PassVar) -> Var {
    Var {
        unc: v.unc,
        lo: v.lo,
        hi: v.hi,
        w: v.w,
        star: v.star,
        pos: v.pos,
        code: v.code,
        nu: v.nu,
    }
}

fn to_pass(v: &Var) -> PassVar {
    PassVar {
        unc: v.unc,
        lo: v.lo,
        hi: v.hi,
        w: v.w,
        star: v.star,
        pos: v.pos,
        code: v.code,
        nu: v.nu,
    }
}

/// The members' residuals `unc - (code bit 0 ? hi : lo)` (saturated) in
/// increasing variable order: `(mask, count, residuals)` (entries past the
/// count 0). `1 <= N <= 8` runs the AVR routine on the AVR.
pub fn members<const N: usize>(var: &[PassVar; N]) -> (usize, usize, [i32; N]) {
    let v: [Var; N] = core::array::from_fn(|i| to_var(&var[i]));
    let mut r = [0; N];
    let (mask, q) = sets::members(&v, &mut r);
    (mask, q, r)
}

/// Each member's multiplier from `out` (in increasing variable order) into
/// its `star`; returns the mask of the members with `code < 2` whose
/// multiplier, negated (saturated) for a lower bound, is below `limit`.
pub fn stars<const N: usize>(var: &mut [PassVar; N], out: &[i32; N], limit: i32) -> u32 {
    let mut v: [Var; N] = core::array::from_fn(|i| to_var(&var[i]));
    let cand = sets::stars(&mut v, out, limit);
    for (p, x) in var.iter_mut().zip(&v) {
        *p = to_pass(x);
    }
    cand
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
    let mut v: [Var; N] = core::array::from_fn(|i| to_var(&var[i]));
    let r = sets::scan(&mut v, out, k, tol);
    for (p, x) in var.iter_mut().zip(&v) {
        *p = to_pass(x);
    }
    r
}
