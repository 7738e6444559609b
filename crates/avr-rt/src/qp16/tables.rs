//! The precomputed tables of a box-constrained parametric QP, in fixed
//! point: the scaled `H^-1`, the unconstrained solution and the bounds as
//! affine rows in theta.

use crate::mac::Row16;

/// One affine row in theta: `round(sum_{j >= start} c_j theta_j /
/// 2^shift) + c0` with Q15.16 `theta`; the coefficients carry `shift - 16`
/// fraction bits beyond Q15.16's (`shift` in `16..=46`), or `shift = 0`
/// for a unit row (`c0 + sum c_j theta_j` with every `c_j` in `{-1, 0,
/// 1}`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Row32<const P: usize> {
    /// The coefficients (raw, `shift` fraction bits).
    pub c: [i32; P],
    /// The constant (Q15.16 raw).
    pub c0: i32,
    /// Fraction bits of the coefficients (16 to 46; 0: a unit row).
    pub shift: u8,
    /// First non-zero coefficient (`P`: the row is the constant).
    pub start: u8,
}

impl<const P: usize> Row32<P> {
    /// The constant row `c0`.
    pub const fn constant(c0: i32) -> Self {
        Row32 {
            c: [0; P],
            c0,
            shift: 16,
            start: P as u8,
        }
    }

    /// The row's value at `theta` (Q15.16), saturated: one rounded MAC, or
    /// for a unit row (`shift == 0`: every coefficient `-1`, `0` or `1`,
    /// as a bound moving with the throttle) sums without products.
    #[inline]
    pub fn eval(&self, theta: &[i32; P]) -> i32 {
        let s = self.start as usize;
        if s >= P {
            return self.c0;
        }
        if self.shift == 0 {
            return self.eval_unit(theta, s);
        }
        self.eval_mac(theta, s)
    }

    /// A unit row from its first non-zero coefficient `s < P` (inlined:
    /// a call would save and restore most registers for a few adds).
    #[inline(never)]
    fn eval_unit(&self, theta: &[i32; P], s: usize) -> i32 {
        let mut acc = self.c0;
        let mut j = s;
        while j < P {
            let c = self.c[j];
            if c == 1 {
                acc = acc.saturating_add(theta[j]);
            } else if c == -1 {
                acc = acc.saturating_sub(theta[j]);
            }
            j += 1;
        }
        acc
    }

    /// A row with products: one rounded MAC from `s < P`.
    #[inline(never)]
    fn eval_mac(&self, theta: &[i32; P], s: usize) -> i32 {
        match (theta.get(s..), self.c.get(s..)) {
            (Some(t), Some(c)) => super::arith::mac_round(t, c, self.shift).saturating_add(self.c0),
            _ => self.c0,
        }
    }
}

/// The tables of the fixed-point dual active-set solver for
/// `min 1/2 z'Hz + q(theta)'z` s.t. `lb(theta) <= z <= ub(theta)` with `N`
/// variables and `P` parameters, in the scaled variables `w = z / 2^s`
/// (`s` = [`Qp16Tables::var_shift`]) and multipliers of the objective
/// times `2^-f` (`f` = [`Qp16Tables::obj_shift`]). Built on the host by
/// `Qp16Tables::from_mpqp` or `Qp16Tables::from_matrices` (feature `std`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qp16Tables<const N: usize, const P: usize> {
    /// `P = 2^f H^-1 / 4^s`, raw with [`Qp16Tables::p_bits`] fraction
    /// bits, row-major (symmetric).
    pub hinv: [[i32; N]; N],
    /// The unconstrained solution `w_unc = -2^-s H^-1 q(theta)`: the high
    /// halves of its 32-bit coefficients `c = 2^16 hi + lo` (`lo` in
    /// `[-2^15, 2^15)`), with `shift - 16` fraction bits (see
    /// [`Qp16Tables::unconstrained`]).
    pub unc_hi: [Row16<P>; N],
    /// The low halves, with `shift` fraction bits.
    pub unc_lo: [Row16<P>; N],
    /// The constants (Q15.16).
    pub unc0: [i32; N],
    /// Lower bounds `lb(theta) / 2^s`; an absent bound is the constant
    /// `i32::MIN`.
    pub lb: [Row32<P>; N],
    /// Upper bounds `ub(theta) / 2^s`; an absent bound is the constant
    /// `i32::MAX`.
    pub ub: [Row32<P>; N],
    /// `s`: `z = w 2^s`.
    pub var_shift: i8,
    /// `f`: the objective's scale in `hinv`.
    pub obj_shift: i8,
    /// Fraction bits of `P`, of the factor's pivots and of the forward
    /// solve's values (16 to 30).
    pub p_bits: u8,
    /// Fraction bits of the unit lower factor `L` (16 to 30).
    pub l_bits: u8,
    /// Fraction bits of the multipliers (16 to 30).
    pub nu_bits: u8,
    /// Smallest bit length of an accepted pivot (raw): smaller ones count
    /// as zero ([`super::Qp16Error::Infeasible`]).
    pub pivot_bits: u8,
    /// A bound counts as violated beyond this (raw Q15.16 of `w`).
    pub primal_tol: i32,
    /// A multiplier has the wrong sign beyond this (raw).
    pub dual_tol: i32,
    /// The most active-set changes per solve.
    pub max_iterations: u16,
}

impl<const N: usize, const P: usize> Qp16Tables<N, P> {
    /// `w_unc` at `theta` (Q15.16): `unc0 + round(hi theta) + round(lo
    /// theta)`, each a rounded 16-bit row and a saturating sum, all rows in
    /// two calls of the AVR rows routine (`Row16::add_all`, about 68
    /// cycles per term).
    #[inline(never)]
    pub fn unconstrained(&self, theta: &[i32; P]) -> [i32; N] {
        let mut out = self.unc0;
        Row16::add_all(&self.unc_hi, theta, &mut out);
        Row16::add_all(&self.unc_lo, theta, &mut out);
        out
    }

    /// `w` (raw Q15.16 of the scaled variables) in the problem's units as
    /// `f64`: `w 2^(s - 16)`.
    pub fn to_problem_f64(&self, w: i32) -> f64 {
        w as f64 * pow2(self.var_shift as i32 - 16)
    }

    /// `w` in the problem's units as `f32`.
    pub fn to_problem_f32(&self, w: i32) -> f32 {
        w as f32 * pow2(self.var_shift as i32 - 16) as f32
    }
}

/// `2^e` for `|e| <= 126` (exact in `f64`).
fn pow2(e: i32) -> f64 {
    let e = e.clamp(-126, 126);
    if e >= 0 {
        (1u128 << e) as f64
    } else {
        1.0 / (1u128 << -e) as f64
    }
}
