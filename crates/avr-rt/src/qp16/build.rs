//! Design time (`std`): the fixed-point tables of a box-constrained
//! parametric QP, with the scaling chosen offline.
//!
//! Scaling (powers of two, so no run-time rescaling):
//! - variables `w = z / 2^s`, with `s` the smallest integer for which every
//!   `|w_unc|`, `|lb|`, `|ub|` over the parameter box is at most `2^13`
//!   (Q15.16 holds `2^15`: the differences of two such values fit);
//! - the objective times `2^f` in the multipliers (`P = 2^f H^-1 / 4^s`,
//!   `nu = 2^-f mu_w`), `f` balancing `|P|` against the bound on `|nu|`
//!   (`sqrt(n) 2R / lambda_min(P)`, `R` the range of `w`): both must stay
//!   below `2^13`, or the problem is refused as too ill-conditioned;
//! - fraction bits (16 to 30) for `P` and the pivots (from `lambda_max(P)`),
//!   for `L` (`|l_ij| <= sqrt(cond P)`; a removal also forms `l^2` and
//!   ratios of pivots up to `cond P` in this format) and for
//!   the multipliers (from their bound), the most that keep each below
//!   `2^31` with two bits to spare,
//!   such that every pivot division stays a single rounded product;
//! - every affine row its own fraction bits (16 to 46), the most that keep
//!   its coefficients below `2^30`.
//!
//! The common variable scale keeps the most-violated rule in the problem's
//! units (a common factor does not change which violation is largest).

use super::sets::Qp16SetTables;
use super::tables::{Qp16Tables, Row32};
use crate::mac::Row16;
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};

/// Why tables could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Qp16BuildError {
    /// A dimension does not match `N`, `P` or another input.
    #[error("dimension mismatch: {0}")]
    Dimension(&'static str),
    /// `H` is not symmetric positive definite.
    #[error("H is not positive definite")]
    NotPositiveDefinite,
    /// An entry is NaN (or an infinity where none may be).
    #[error("non-finite input")]
    NonFinite,
    /// A constraint row of the mpQP bounds more than one variable, or two
    /// rows bound the same side of one variable.
    #[error("not a box-constrained problem: {0}")]
    NotBox(String),
    /// The scaled values do not fit Q15.16 (an ill-conditioned `H` or a
    /// coefficient too large).
    #[error("not representable in Q15.16: {0}")]
    Range(String),
}

/// The scaling the builder chose, and the ranges it proved on the box.
#[derive(Clone, Debug, PartialEq)]
pub struct Qp16Scaling {
    /// `s`: `z = 2^s w`.
    pub var_shift: i8,
    /// `f`: `P = 2^f H^-1 / 4^s`.
    pub obj_shift: i8,
    /// Largest `|w|` of the unconstrained solution and finite bounds on the
    /// parameter box (scaled units).
    pub w_range: f64,
    /// Largest `|P_ij|`.
    pub p_max: f64,
    /// The bound on `|nu|` (scaled).
    pub nu_bound: f64,
    /// Eigenvalue range of `P`.
    pub p_eigen: (f64, f64),
}

/// A parametric QP `min 1/2 z'Hz + (Q theta + q0)'z` s.t. `lb_theta theta
/// + lb0 <= z <= ub_theta theta + ub0` (row-major slices; infinite `lb0`,
/// `ub0` entries are absent bounds, their rows must be zero) on the
/// parameter box `theta_lb <= theta <= theta_ub`.
#[derive(Clone, Copy, Debug)]
pub struct BoxQp<'a> {
    /// `H`, `n x n`.
    pub h: &'a [f64],
    /// `Q`, `n x p`.
    pub q_theta: &'a [f64],
    /// `q0`, `n`.
    pub q0: &'a [f64],
    /// `n x p`.
    pub lb_theta: &'a [f64],
    /// `n`.
    pub lb0: &'a [f64],
    /// `n x p`.
    pub ub_theta: &'a [f64],
    /// `n`.
    pub ub0: &'a [f64],
    /// `p`.
    pub theta_lb: &'a [f64],
    /// `p`.
    pub theta_ub: &'a [f64],
}

/// The tolerances and cap written into the tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qp16Settings {
    /// [`Qp16Tables::primal_tol`] (raw Q15.16 of `w`). Default 2.
    pub primal_tol: i32,
    /// [`Qp16Tables::dual_tol`] (raw). Default 2.
    pub dual_tol: i32,
    /// [`Qp16Tables::max_iterations`]. Default 100.
    pub max_iterations: u16,
}

impl Default for Qp16Settings {
    fn default() -> Self {
        Qp16Settings {
            primal_tol: 2,
            dual_tol: 2,
            max_iterations: 100,
        }
    }
}

/// The box form of an mpQP whose every constraint row bounds one
/// variable (`g z_i <= W + E theta`): `(H, Q, q0, lb_theta, lb0, ub_theta,
/// ub0)` as row-major vectors, with `q = F' theta + f`.
#[allow(clippy::type_complexity)]
pub fn box_form(
    p: &MpqpProblem,
) -> Result<
    (
        Vec<f64>,
        Vec<f64>,
        Vec<f64>,
        Vec<f64>,
        Vec<f64>,
        Vec<f64>,
        Vec<f64>,
    ),
    Qp16BuildError,
> {
    let (n, np) = (p.n(), p.p());
    let h: Vec<f64> = (0..n * n).map(|k| p.h[(k / n, k % n)]).collect();
    let q: Vec<f64> = (0..n * np).map(|k| p.f_theta[(k % np, k / np)]).collect();
    let q0: Vec<f64> = p.f.iter().copied().collect();
    let mut lbt = vec![0.0; n * np];
    let mut ubt = vec![0.0; n * np];
    let mut lb0 = vec![f64::NEG_INFINITY; n];
    let mut ub0 = vec![f64::INFINITY; n];
    let (mut has_lo, mut has_hi) = (vec![false; n], vec![false; n]);
    for r in 0..p.m() {
        let nz: Vec<usize> = (0..n).filter(|&j| p.g[(r, j)] != 0.0).collect();
        let &[i] = nz.as_slice() else {
            return Err(Qp16BuildError::NotBox(format!(
                "row {r} has {} non-zero entries",
                nz.len()
            )));
        };
        let g = p.g[(r, i)];
        // g z_i <= W + E theta: z_i <= (W + E theta) / g for g > 0, >= for g < 0.
        let (rows, c0, seen) = if g > 0.0 {
            (&mut ubt, &mut ub0, &mut has_hi)
        } else {
            (&mut lbt, &mut lb0, &mut has_lo)
        };
        if seen[i] {
            return Err(Qp16BuildError::NotBox(format!(
                "two rows bound the same side of variable {i}"
            )));
        }
        seen[i] = true;
        c0[i] = p.w[r] / g;
        for j in 0..np {
            rows[i * np + j] = p.e[(r, j)] / g + 0.0;
        }
    }
    Ok((h, q, q0, lbt, lb0, ubt, ub0))
}

/// A 32-bit row as its 16-bit high and low halves (`c = 2^16 hi + lo`,
/// `lo` in `[-2^15, 2^15)`; a unit row is all high half, shift 0).
fn split_row<const P: usize>(r: &Row32<P>) -> (Row16<P>, Row16<P>) {
    let (mut hi, mut lo) = ([0i16; P], [0i16; P]);
    for (k, &c) in r.c.iter().enumerate() {
        let l = if r.shift == 0 { 0 } else { c as i16 };
        lo[k] = l;
        hi[k] = ((c as i64 - l as i64) >> if r.shift == 0 { 0 } else { 16 }) as i16;
    }
    let start = |v: &[i16; P]| v.iter().position(|&x| x != 0).unwrap_or(P) as u8;
    let hs = r.shift.saturating_sub(16);
    (
        Row16::new(hi, hs, start(&hi)),
        Row16::new(lo, r.shift, start(&lo)),
    )
}

/// Largest `|a' theta + c|` on the box.
fn row_range(a: &[f64], c: f64, lo: &[f64], hi: &[f64]) -> f64 {
    let mut mid = c;
    let mut half = 0.0;
    for ((&g, &l), &u) in a.iter().zip(lo).zip(hi) {
        mid += g * 0.5 * (l + u);
        half += g.abs() * 0.5 * (u - l);
    }
    mid.abs() + half
}

fn quantise_row<const P: usize>(a: &[f64], c: f64, scale: f64) -> Result<Row32<P>, Qp16BuildError> {
    let amax = a.iter().fold(0.0f64, |m, v| m.max(v.abs())) * scale;
    let c0 = c * scale * 65_536.0;
    if !c0.is_finite() || c0.abs() >= 2f64.powi(31) {
        return Err(Qp16BuildError::Range(format!("row constant {c}")));
    }
    // A unit row (coefficients 0 or +-1 after scaling): sums only.
    if a.iter().all(|&v| [0.0, 1.0, -1.0].contains(&(v * scale))) {
        let mut row = Row32::constant(c0.round() as i32);
        row.shift = 0;
        for (k, v) in a.iter().enumerate().take(P) {
            row.c[k] = (v * scale) as i32;
        }
        row.start = row.c.iter().position(|&v| v != 0).unwrap_or(P) as u8;
        return Ok(row);
    }
    let mut shift = 46u8;
    while shift > 16 && amax * 2f64.powi(shift as i32) >= 2f64.powi(30) {
        shift -= 1;
    }
    if amax * 2f64.powi(shift as i32) >= 2f64.powi(30) {
        return Err(Qp16BuildError::Range(format!("row coefficient {amax}")));
    }
    let mut row = Row32::constant(c0.round() as i32);
    row.shift = shift;
    for (k, v) in a.iter().enumerate().take(P) {
        row.c[k] = (v * scale * 2f64.powi(shift as i32)).round() as i32;
    }
    row.start = row.c.iter().position(|&v| v != 0).unwrap_or(P) as u8;
    Ok(row)
}

impl<const N: usize, const P: usize> Qp16Tables<N, P> {
    /// The tables of a box-constrained QP (see [`BoxQp`]) and the scaling
    /// chosen.
    ///
    /// # Errors
    /// [`Qp16BuildError`].
    pub fn from_matrices(
        qp: &BoxQp<'_>,
        settings: Qp16Settings,
    ) -> Result<(Self, Qp16Scaling), Qp16BuildError> {
        let dims = [
            (qp.h.len(), N * N, "H"),
            (qp.q_theta.len(), N * P, "Q"),
            (qp.q0.len(), N, "q0"),
            (qp.lb_theta.len(), N * P, "lb_theta"),
            (qp.lb0.len(), N, "lb0"),
            (qp.ub_theta.len(), N * P, "ub_theta"),
            (qp.ub0.len(), N, "ub0"),
            (qp.theta_lb.len(), P, "theta_lb"),
            (qp.theta_ub.len(), P, "theta_ub"),
        ];
        if let Some(&(_, _, what)) = dims.iter().find(|(a, b, _)| a != b) {
            return Err(Qp16BuildError::Dimension(what));
        }
        if N == 0 || N > 64 {
            return Err(Qp16BuildError::Dimension("N must be 1..=64"));
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(finite(qp.h)
            && finite(qp.q_theta)
            && finite(qp.q0)
            && finite(qp.lb_theta)
            && finite(qp.ub_theta)
            && finite(qp.theta_lb)
            && finite(qp.theta_ub))
            || qp.lb0.iter().chain(qp.ub0).any(|v| v.is_nan())
        {
            return Err(Qp16BuildError::NonFinite);
        }
        let h = DMatrix::from_row_slice(N, N, qp.h);
        let h = (&h + h.transpose()) * 0.5;
        let chol = h
            .clone()
            .cholesky()
            .ok_or(Qp16BuildError::NotPositiveDefinite)?;
        let hinv = chol.inverse();
        let q = DMatrix::from_row_slice(N, P, qp.q_theta);
        let k = -&hinv * q;
        let k0 = -&hinv * DVector::from_column_slice(qp.q0);
        let (tl, tu) = (qp.theta_lb, qp.theta_ub);
        // The range of every row on the box.
        let mut range = 0.0f64;
        for i in 0..N {
            let ki: Vec<f64> = k.row(i).iter().copied().collect();
            range = range.max(row_range(&ki, k0[i], tl, tu));
            for (rows, c0) in [(qp.lb_theta, qp.lb0), (qp.ub_theta, qp.ub0)] {
                if c0[i].is_finite() {
                    range = range.max(row_range(&rows[i * P..(i + 1) * P], c0[i], tl, tu));
                }
            }
        }
        let s = (range.max(1e-300) / 8192.0)
            .log2()
            .ceil()
            .clamp(-30.0, 30.0) as i32;
        let scale = 2f64.powi(-s);
        let w_range = range * scale;
        let pw = &hinv * (scale * scale);
        let eig = pw.clone().symmetric_eigen().eigenvalues;
        let (emin, emax) = eig
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
        if emin <= 0.0 {
            return Err(Qp16BuildError::NotPositiveDefinite);
        }
        let nu_num = (N as f64).sqrt() * 2.0 * w_range.max(1.0);
        // The objective scale balancing |P| against the multipliers' bound.
        let f = (0.5 * (nu_num / (emin * emax)).log2())
            .round()
            .clamp(-30.0, 30.0) as i32;
        let c = 2f64.powi(f);
        let p_max = pw.iter().fold(0.0f64, |m, v| m.max(v.abs())) * c;
        let (lmin, lmax) = (emin * c, emax * c);
        let nu_bound = nu_num / lmin;
        if lmax.max(p_max) >= 8192.0 || nu_bound >= 8192.0 {
            return Err(Qp16BuildError::Range(format!(
                "H^-1 too ill-conditioned for Q15.16: |P| {p_max:.3e}, |nu| <= {nu_bound:.3e}"
            )));
        }
        // Fraction bits: P, pivots and forward-solve values (<= lambda_max
        // in size), L (|l| <= sqrt(cond)), the multipliers (<= nu_bound).
        let bits = |m: f64| (29 - m.max(1e-9).log2().ceil() as i32).clamp(16, 30) as u8;
        // (The removal's rank-one update forms l^2 and alpha / d, both up
        // to cond P, in L's format.)
        let cond = lmax / lmin * 1.01;
        let p_bits = bits(lmax.max(p_max));
        let l_bits = bits(cond.max(4.0 * cond.sqrt()));
        let mut nu_bits = bits(nu_bound);
        // Every division round(x 2^k / d) needs b + 29 - k >= 16 for the
        // pivot's bit length b >= pivot_bits (pivots are >= lambda_min).
        let pivot_room = (lmin * 0.5 * 2f64.powi(p_bits as i32)).log2().floor() as i32 + 1;
        let pivot_bits = |nb: u8| {
            [l_bits, nb + p_bits - 16, p_bits]
                .into_iter()
                .max()
                .unwrap_or(16) as i32
                - 13
        };
        while pivot_bits(nu_bits) > pivot_room && nu_bits > 16 {
            nu_bits -= 1;
        }
        if pivot_bits(nu_bits) > pivot_room {
            return Err(Qp16BuildError::Range(format!(
                "pivots as small as {lmin:.3e} against |P| {p_max:.3e}"
            )));
        }
        let mut hinv16 = [[0i32; N]; N];
        for (i, row) in hinv16.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (pw[(i, j)] * c * 2f64.powi(p_bits as i32)).round() as i32;
            }
        }
        let mut unc_hi = [Row16::new([0; P], 0, P as u8); N];
        let mut unc_lo = [Row16::new([0; P], 0, P as u8); N];
        let mut unc0 = [0i32; N];
        let mut lb = [Row32::constant(i32::MIN); N];
        let mut ub = [Row32::constant(i32::MAX); N];
        for i in 0..N {
            let ki: Vec<f64> = k.row(i).iter().copied().collect();
            let row: Row32<P> = quantise_row(&ki, k0[i], scale)?;
            (unc_hi[i], unc_lo[i]) = split_row(&row);
            unc0[i] = row.c0;
            if qp.lb0[i].is_finite() {
                lb[i] = quantise_row(&qp.lb_theta[i * P..(i + 1) * P], qp.lb0[i], scale)?;
            } else if qp.lb0[i] == f64::INFINITY {
                return Err(Qp16BuildError::NonFinite);
            }
            if qp.ub0[i].is_finite() {
                ub[i] = quantise_row(&qp.ub_theta[i * P..(i + 1) * P], qp.ub0[i], scale)?;
            } else if qp.ub0[i] == f64::NEG_INFINITY {
                return Err(Qp16BuildError::NonFinite);
            }
        }
        let tables = Qp16Tables {
            hinv: hinv16,
            unc_hi,
            unc_lo,
            unc0,
            lb,
            ub,
            var_shift: s as i8,
            obj_shift: f as i8,
            p_bits,
            l_bits,
            nu_bits,
            pivot_bits: pivot_bits(nu_bits).max(1) as u8,
            primal_tol: settings.primal_tol,
            dual_tol: settings.dual_tol,
            max_iterations: settings.max_iterations,
        };
        let scaling = Qp16Scaling {
            var_shift: s as i8,
            obj_shift: f as i8,
            w_range,
            p_max,
            nu_bound,
            p_eigen: (lmin, lmax),
        };
        Ok((tables, scaling))
    }

    /// The tables of a `kestrel.mpqp.v1` problem whose every constraint
    /// row bounds one variable ([`box_form`]).
    ///
    /// # Errors
    /// [`Qp16BuildError`].
    pub fn from_mpqp(
        p: &MpqpProblem,
        settings: Qp16Settings,
    ) -> Result<(Self, Qp16Scaling), Qp16BuildError> {
        if p.n() != N || p.p() != P {
            return Err(Qp16BuildError::Dimension("mpQP size is not N x P"));
        }
        let (h, q, q0, lbt, lb0, ubt, ub0) = box_form(p)?;
        let tl: Vec<f64> = p.theta_lb.iter().copied().collect();
        let tu: Vec<f64> = p.theta_ub.iter().copied().collect();
        let qp = BoxQp {
            h: &h,
            q_theta: &q,
            q0: &q0,
            lb_theta: &lbt,
            lb0: &lb0,
            ub_theta: &ubt,
            ub0: &ub0,
            theta_lb: &tl,
            theta_ub: &tu,
        };
        Self::from_matrices(&qp, settings)
    }

    /// The per-active-set tables of [`super::Qp16SetSolver`] (`S = 2^N`,
    /// `E = N^2 2^(N-1)`), from this table's `P` (inverted in `f64` per
    /// set, then rounded).
    ///
    /// # Errors
    /// [`Qp16BuildError::Dimension`] unless `S = 2^N`, `E = N^2 2^(N-1)`
    /// and `N <= 10`; [`Qp16BuildError::Range`] if an entry does not fit.
    pub fn set_tables<const S: usize, const E: usize>(
        &self,
    ) -> Result<Qp16SetTables<N, S, E>, Qp16BuildError> {
        if N > 10 || S != 1 << N || E != N * N * (1 << N) / 2 {
            return Err(Qp16BuildError::Dimension(
                "S = 2^N, E = N^2 2^(N-1), N <= 10",
            ));
        }
        let pf = |i: usize, j: usize| self.hinv[i][j] as f64 / 2f64.powi(self.p_bits as i32);
        let mut blocks: Vec<(Vec<f64>, Vec<f64>)> = Vec::with_capacity(S);
        let (mut mmax, mut wmax) = (0.0f64, 0.0f64);
        for mask in 0..S {
            let a: Vec<usize> = (0..N).filter(|j| mask >> j & 1 == 1).collect();
            let inact: Vec<usize> = (0..N).filter(|j| mask >> j & 1 == 0).collect();
            let k = a.len();
            let m = DMatrix::from_fn(k, k, |r, c| pf(a[r], a[c]));
            let minv = if k == 0 {
                m
            } else {
                m.cholesky()
                    .ok_or(Qp16BuildError::NotPositiveDefinite)?
                    .inverse()
            };
            let pia = DMatrix::from_fn(inact.len(), k, |r, c| pf(inact[r], a[c]));
            let w = pia * &minv;
            mmax = minv.iter().fold(mmax, |x, v| x.max(v.abs()));
            wmax = w.iter().fold(wmax, |x, v| x.max(v.abs()));
            // Row-major.
            let mv: Vec<f64> = (0..k * k).map(|t| minv[(t / k, t % k)]).collect();
            let wv: Vec<f64> = (0..inact.len() * k).map(|t| w[(t / k, t % k)]).collect();
            blocks.push((mv, wv));
        }
        // Fraction bits of the form 8 m + 1 (17 or 25): the rounding shift
        // of every MAC is then whole bytes (no bit loop on the AVR).
        let bits = |m: f64| {
            let b = (29 - m.max(1e-9).log2().ceil() as i32).clamp(17, 30);
            (b - (b - 1) % 8) as u8
        };
        // One shift for the whole block (one call of the rows routine).
        let minv_bits = bits(mmax).min(bits(wmax));
        let w_bits = minv_bits;
        if mmax * 2f64.powi(minv_bits as i32) >= 2f64.powi(31)
            || wmax * 2f64.powi(w_bits as i32) >= 2f64.powi(31)
        {
            return Err(Qp16BuildError::Range(format!(
                "per-set tables: |M^-1| {mmax:.3e}, |W| {wmax:.3e}"
            )));
        }
        let mut out = Qp16SetTables {
            offset: [0; S],
            data: [0; E],
            minv_bits,
            w_bits,
        };
        let mut at = 0usize;
        for (mask, (mv, wv)) in blocks.iter().enumerate() {
            out.offset[mask] = at as u16;
            for v in mv {
                out.data[at] = (v * 2f64.powi(minv_bits as i32)).round() as i32;
                at += 1;
            }
            for v in wv {
                out.data[at] = (v * 2f64.powi(w_bits as i32)).round() as i32;
                at += 1;
            }
        }
        Ok(out)
    }

    /// The Rust source of these tables as a `static` named `name` (for
    /// firmware and the AVR bench).
    pub fn to_rust(&self, name: &str) -> String {
        let row = |r: &Row32<P>| {
            format!(
                "kestrel_avr_rt::qp16::Row32 {{ c: {:?}, c0: {}, shift: {}, start: {} }}",
                r.c, r.c0, r.shift, r.start
            )
        };
        let row16 = |r: &Row16<P>| {
            format!(
                "kestrel_avr_rt::mac::Row16 {{ c: {:?}, shift: {}, start: {} }}",
                r.c, r.shift, r.start
            )
        };
        let rows = |rs: &[Row32<P>; N]| rs.iter().map(row).collect::<Vec<_>>().join(",\n        ");
        let rows16 =
            |rs: &[Row16<P>; N]| rs.iter().map(row16).collect::<Vec<_>>().join(",\n        ");
        format!(
            "static {name}: kestrel_avr_rt::qp16::Qp16Tables<{N}, {P}> = kestrel_avr_rt::qp16::Qp16Tables {{\n    hinv: {:?},\n    unc_hi: [\n        {}\n    ],\n    unc_lo: [\n        {}\n    ],\n    unc0: {:?},\n    lb: [\n        {}\n    ],\n    ub: [\n        {}\n    ],\n    var_shift: {},\n    obj_shift: {},\n    p_bits: {},\n    l_bits: {},\n    nu_bits: {},\n    pivot_bits: {},\n    primal_tol: {},\n    dual_tol: {},\n    max_iterations: {},\n}};\n",
            self.hinv,
            rows16(&self.unc_hi),
            rows16(&self.unc_lo),
            self.unc0,
            rows(&self.lb),
            rows(&self.ub),
            self.var_shift,
            self.obj_shift,
            self.p_bits,
            self.l_bits,
            self.nu_bits,
            self.pivot_bits,
            self.primal_tol,
            self.dual_tol,
            self.max_iterations
        )
    }
}

/// `theta` in Q15.16 raw (rounded, saturated).
pub fn theta_q16<const P: usize>(theta: &[f64]) -> [i32; P] {
    core::array::from_fn(|j| {
        let v = theta.get(j).copied().unwrap_or(0.0) * 65_536.0;
        v.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32
    })
}

impl<const N: usize, const S: usize, const E: usize> Qp16SetTables<N, S, E> {
    /// The Rust source of these tables as a `static` named `name`.
    pub fn to_rust(&self, name: &str) -> String {
        format!(
            "static {name}: kestrel_avr_rt::qp16::Qp16SetTables<{N}, {S}, {E}> = kestrel_avr_rt::qp16::Qp16SetTables {{\n    offset: {:?},\n    data: {:?},\n    minv_bits: {},\n    w_bits: {},\n}};\n",
            self.offset, self.data, self.minv_bits, self.w_bits
        )
    }
}
