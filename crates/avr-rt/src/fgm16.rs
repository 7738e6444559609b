//! [`Fgm16Law`]: kestrel-fgm's fast gradient method with its iterations in
//! fixed point on the AVR's hardware multiplier.
//!
//! The same algorithm as `kestrel_fgm::FgmTables::solve_with` (initial
//! projected gradient step from the box centre or the previous solution,
//! then `z+ = clamp(M y + c)`, `y+ = z+ + beta (z+ - z)`), split in two:
//!
//! - **set-up**, once per solve, in the loop's scalar `S` (f32 or
//!   `Q16Mac`): `c = K theta + k0`, the box `lo`, `hi` from theta;
//! - **iterations** in Q15.16 (`i32`) with the rows of `M` as 16-bit
//!   coefficients with their own binary point ([`Row16`], exact sums of
//!   6 or 8 hardware multiplies per term, one rounding per row, all rows of an
//!   iteration in one assembly call: [`Row16::apply_all`]) and the
//!   momentum `beta` in Q1.15: about a quarter of the work of a 32 x
//!   32-bit MAC.
//!
//! The certificate of kestrel-fgm bounds the iteration count for the exact
//! arithmetic; the rounding of this kernel is measured against the exact
//! optimum in `tests/fgm16_accuracy.rs` (the input error stays below 1 us
//! with the certified count; see the crate README).
//!
//! ```
//! use kestrel_avr_rt::fgm16::Fgm16Law;
//! use kestrel_avr_rt::kalman16::Row16;
//! use kestrel_core::{ControlLaw, Matrix};
//! use kestrel_fgm::FgmTables;
//! // One variable, theta = [x, r]: minimise (z - (r - x))^2 / 2 on [-1, 1]
//! // (M = 0, K = [-1, 1]: one gradient step is exact).
//! let t = FgmTables::<f32, 1, 2, 1> {
//!     m: Matrix::from_rows([[0.0]]), k_theta: Matrix::from_rows([[-1.0, 1.0]]), k0: [0.0],
//!     lo_theta: Matrix::zeros(), lo0: [-1.0], hi_theta: Matrix::zeros(), hi0: [1.0],
//!     d: [1.0], d_inv: [1.0], betas: [0.0], iterations: 3, warm_iterations: 3, shift: 0,
//! };
//! let m16 = [Row16::new([0], 15, 1)];
//! let mut law = Fgm16Law::<f32, 1, 2, 1, 1>::new(t, m16, [0], 1, false, 3).unwrap();
//! let mut u = [0.0];
//! law.control(&[0.25], &[0.5], &mut u).unwrap();
//! assert!((u[0] - 0.25).abs() < 1e-4);
//! law.control(&[0.0], &[5.0], &mut u).unwrap();
//! assert_eq!(u[0], 1.0); // the box
//! ```

use crate::cycles::{Deadline, NoDeadline};
use crate::kalman16::mul_q15;
use crate::law::LawInfo;
use crate::law::{check_law_sizes, pack_theta};
use crate::mac::Row16;
use crate::output::RtScalar;
use kestrel_core::{ControlLaw, Error, all_finite};
use kestrel_fgm::FgmTables;

/// The fast gradient law with fixed-point iterations (see the module docs):
/// `N` variables, `P` parameters (`nx` states then the references), `T`
/// momentum entries, `NU` inputs applied (the first `NU` variables).
#[derive(Clone, Debug)]
pub struct Fgm16Law<S, const N: usize, const P: usize, const T: usize, const NU: usize> {
    setup: FgmTables<S, N, P, T>,
    /// First non-zero column of each row of `lo_theta`, `hi_theta`,
    /// `k_theta` (the tricopter's box depends on the throttle alone).
    starts: [[u8; N]; 3],
    m: [Row16<N>; N],
    betas: [i16; T],
    nx: usize,
    warm: bool,
    certified: u16,
    /// Iterations run in the last solve (below `certified` when its
    /// deadline stopped it).
    done: u16,
    /// Last solution in scaled units (Q15.16), for warm starts.
    last: Option<[i32; N]>,
}

/// Fraction bits of every row of `M` (`|M_ij| <= 1` for `M = I - D H D / L`
/// with `L >= lambda_max`, so Q1.15 holds it). The rows of `M` run in one
/// call of the assembly rows routine ([`Row16::apply_all`]) per iteration.
pub const M_SHIFT: u8 = 15;

/// The box and linear term of one solve in Q15.16.
struct Box16<const N: usize> {
    lo: [i32; N],
    hi: [i32; N],
    c: [i32; N],
}

#[inline(always)]
#[allow(clippy::needless_range_loop)] // several arrays indexed together
fn step<const N: usize>(m: &[Row16<N>; N], y: &[i32; N], b: &Box16<N>, w: &mut [i32; N]) {
    let my = Row16::apply_all(m, y);
    for i in 0..N {
        w[i] = crate::clamp::clamp(my[i].saturating_add(b.c[i]), b.lo[i], b.hi[i]);
    }
}

/// Asks the deadline, in a call of its own: inlined into [`iterate`],
/// its state and the clock read made the loop's stack frame too large for
/// the AVR's short `Y+q` addressing, and every iteration slower (about 240
/// cycles per iteration more in the firmware; about 160 as a call, hence
/// [`Deadline::STRIDE`]).
#[inline(never)]
fn expired<D: Deadline>(deadline: &mut D) -> bool {
    deadline.expired()
}

/// The initial projected gradient step from `y` and up to `iterations`
/// iterations, all in Q15.16, checking `deadline` before every
/// `D::STRIDE`-th iteration;
/// returns `z` (projected onto the box after every step) and the number
/// of iterations run. Not inlined: a small function
/// of its own keeps its state in registers and a short stack frame on the
/// AVR (inlined into the firmware's large `main`, every access to a local
/// costs several instructions).
#[inline(never)]
#[allow(clippy::needless_range_loop)] // several arrays indexed together
fn iterate<const N: usize, D: Deadline>(
    m: &[Row16<N>; N],
    betas: &[i16],
    b: &Box16<N>,
    mut y: [i32; N],
    iterations: u16,
    deadline: &mut D,
) -> ([i32; N], u16) {
    let mut w = [0i32; N];
    step(m, &y, b, &mut w);
    let mut z = w;
    y = w;
    let last_beta = betas.last().copied().unwrap_or(0);
    for k in 0..iterations {
        if !D::NEVER && k % D::STRIDE.max(1) == 0 && expired(deadline) {
            return (z, k);
        }
        let beta = betas.get(k as usize).copied().unwrap_or(last_beta);
        step(m, &y, b, &mut w);
        for i in 0..N {
            let dz = w[i].saturating_sub(z[i]);
            y[i] = w[i].saturating_add(mul_q15(dz, beta));
            z[i] = w[i];
        }
    }
    (z, iterations)
}

impl<S: RtScalar, const N: usize, const P: usize, const T: usize, const NU: usize>
    Fgm16Law<S, N, P, T, NU>
{
    /// A law from kestrel-fgm's tables in `S` (for the set-up and the
    /// scaling; their `m` and `betas` are not used), the rows of `M` in
    /// 16 bits, the momentum table in Q1.15, `nx` states in theta, warm or
    /// cold start, and the iteration count.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `nx > P` or `NU > N`;
    /// [`Error::InvalidArgument`] without iterations, with an empty
    /// momentum table or a row of `M` not in Q1.15; [`Error::NonFinite`]
    /// with non-finite tables.
    pub fn new(
        setup: FgmTables<S, N, P, T>,
        m: [Row16<N>; N],
        betas: [i16; T],
        nx: usize,
        warm: bool,
        iterations: u16,
    ) -> Result<Self, Error> {
        check_law_sizes::<N, P, NU>(nx)?;
        if iterations == 0 || T == 0 {
            return Err(Error::InvalidArgument(
                "fast gradient with zero iterations or no momentum",
            ));
        }
        if m.iter().any(|r| r.shift != M_SHIFT) {
            return Err(Error::InvalidArgument(
                "M rows must have 15 fraction bits (M_SHIFT)",
            ));
        }
        let finite = setup.k_theta.is_finite()
            && setup.lo_theta.is_finite()
            && setup.hi_theta.is_finite()
            && all_finite(&setup.k0)
            && all_finite(&setup.lo0)
            && all_finite(&setup.hi0)
            && all_finite(&setup.d);
        if !finite {
            return Err(Error::NonFinite);
        }
        let first = |rows: &[[S; P]; N]| -> [u8; N] {
            core::array::from_fn(|i| {
                rows.get(i)
                    .and_then(|r| r.iter().position(|v| *v != S::ZERO))
                    .unwrap_or(P) as u8
            })
        };
        let starts = [
            first(&setup.lo_theta.data),
            first(&setup.hi_theta.data),
            first(&setup.k_theta.data),
        ];
        Ok(Fgm16Law {
            setup,
            starts,
            m,
            betas,
            nx,
            warm,
            certified: iterations,
            done: 0,
            last: None,
        })
    }

    /// The iteration count (the certified one the law was made with).
    pub fn certified_iterations(&self) -> u16 {
        self.certified
    }

    /// Whether the last solve stopped before the certified count (its
    /// deadline expired): its input is feasible (in the box) but the
    /// certificate's accuracy does not hold for that period.
    pub fn truncated(&self) -> bool {
        self.done < self.certified
    }

    /// Solves for `theta` with every iteration and returns the solution in
    /// the problem's units (all `N` variables).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite theta (or a set-up that
    /// overflows), [`Error::Infeasible`] if the box is empty.
    pub fn solve(&mut self, theta: &[S; P]) -> Result<[S; N], Error> {
        self.solve_until(theta, &mut NoDeadline)
    }

    /// [`Fgm16Law::solve`], asking `deadline` before every iteration (every
    /// [`Deadline::STRIDE`]-th): once
    /// it has expired the solve stops with its current iterate (projected
    /// onto the box: a valid, bounded input) after at least the initial
    /// projected gradient step. [`LawInfo::iterations`] then reports the
    /// iterations run and [`Fgm16Law::truncated`] is true.
    ///
    /// # Errors
    /// As [`Fgm16Law::solve`].
    #[allow(clippy::needless_range_loop)] // several arrays indexed together
    #[inline(never)]
    pub fn solve_until<D: Deadline>(
        &mut self,
        theta: &[S; P],
        deadline: &mut D,
    ) -> Result<[S; N], Error> {
        if !all_finite(theta) {
            return Err(Error::NonFinite);
        }
        let t = &self.setup;
        let mut b = Box16 {
            lo: [0; N],
            hi: [0; N],
            c: [0; N],
        };
        // Affine maps from theta, skipping each row's leading zeros.
        let dot = |row: &[S; P], s: u8| -> S {
            let s = (s as usize).min(P);
            match (row.get(s..), theta.get(s..)) {
                (Some(r), Some(t)) if !r.is_empty() => S::dot(r, t),
                _ => S::ZERO,
            }
        };
        for i in 0..N {
            let lo = dot(&t.lo_theta.data[i], self.starts[0][i]) + t.lo0[i];
            let hi = dot(&t.hi_theta.data[i], self.starts[1][i]) + t.hi0[i];
            let c = dot(&t.k_theta.data[i], self.starts[2][i]) + t.k0[i];
            b.lo[i] = lo.to_q16().ok_or(Error::NonFinite)?;
            b.hi[i] = hi.to_q16().ok_or(Error::NonFinite)?;
            b.c[i] = c.to_q16().ok_or(Error::NonFinite)?;
            if b.lo[i] > b.hi[i] {
                return Err(Error::Infeasible);
            }
        }
        let mut y = [0i32; N];
        match (self.warm, self.last) {
            (true, Some(z0)) => y = z0,
            _ => {
                for i in 0..N {
                    y[i] = ((b.lo[i] as i64 + b.hi[i] as i64) >> 1) as i32;
                }
            }
        }
        for i in 0..N {
            y[i] = crate::clamp::clamp(y[i], b.lo[i], b.hi[i]);
        }
        let (z, done) = iterate(&self.m, &self.betas, &b, y, self.certified, deadline);
        self.done = done;
        self.last = Some(z);
        let mut out = [S::ZERO; N];
        for i in 0..N {
            out[i] = S::from_q16(z[i]) * t.d[i];
        }
        Ok(out)
    }
}

impl<S: RtScalar, const N: usize, const P: usize, const T: usize, const NU: usize> ControlLaw
    for Fgm16Law<S, N, P, T, NU>
{
    type Scalar = S;
    crate::law::parametric_law_sizes!();
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        self.control_until(x, r, u, &mut NoDeadline)
    }
}

impl<S: RtScalar, const N: usize, const P: usize, const T: usize, const NU: usize>
    Fgm16Law<S, N, P, T, NU>
{
    /// [`ControlLaw::control`] with a deadline ([`Fgm16Law::solve_until`]).
    ///
    /// # Errors
    /// As [`ControlLaw::control`].
    pub fn control_until<D: Deadline>(
        &mut self,
        x: &[S],
        r: &[S],
        u: &mut [S],
        deadline: &mut D,
    ) -> Result<(), Error> {
        let theta: [S; P] = pack_theta(self.nx, NU, x, r, u)?;
        let z = self.solve_until(&theta, deadline)?;
        u.copy_from_slice(&z[..NU]);
        Ok(())
    }
}

impl<S: RtScalar, const N: usize, const P: usize, const T: usize, const NU: usize> LawInfo
    for Fgm16Law<S, N, P, T, NU>
{
    /// Iterations run in the last solve (the certified count unless a
    /// deadline stopped it; 0 before the first).
    fn iterations(&self) -> u16 {
        self.done
    }
    fn restart(&mut self) {
        self.last = None;
    }
}

/// An [`Fgm16Law`] with a [`Deadline`] checked between its iterations, as
/// a [`ControlLaw`] (the firmware's: a [`crate::cycles::CycleBudget`]
/// restarted at each period's tick).
#[derive(Clone, Debug)]
pub struct Fgm16Deadline<L, D> {
    /// The law.
    pub law: L,
    /// The deadline of each solve.
    pub deadline: D,
}

impl<S: RtScalar, const N: usize, const P: usize, const T: usize, const NU: usize, D: Deadline>
    ControlLaw for Fgm16Deadline<Fgm16Law<S, N, P, T, NU>, D>
{
    type Scalar = S;
    fn nx(&self) -> usize {
        self.law.nx()
    }
    fn nr(&self) -> usize {
        self.law.nr()
    }
    fn nu(&self) -> usize {
        self.law.nu()
    }
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        self.law.control_until(x, r, u, &mut self.deadline)
    }
}

impl<L: LawInfo, D> LawInfo for Fgm16Deadline<L, D> {
    fn iterations(&self) -> u16 {
        self.law.iterations()
    }
    fn restart(&mut self) {
        self.law.restart()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel_fgm::{FgmWorkspace, Start};

    /// The MPC law's test tables with the scaling `D = diag(2, 0.5)`.
    fn tables() -> FgmTables<f64, 2, 3, 1> {
        FgmTables {
            d: [2.0, 0.5],
            d_inv: [0.5, 2.0],
            ..crate::law::tests::tables()
        }
    }

    // M = [[0.5, 0.1], [0.1, 0.4]] with 15 fraction bits; beta 0.2 in Q1.15.
    fn m16() -> [Row16<2>; 2] {
        [
            Row16::new([16384, 3277], 15, 0),
            Row16::new([3277, 13107], 15, 0),
        ]
    }

    #[test]
    fn matches_kestrel_fgm_within_the_rounding() {
        let t = tables();
        let mut law = Fgm16Law::<f64, 2, 3, 1, 2>::new(t, m16(), [6554], 2, false, 30).unwrap();
        let mut ws = FgmWorkspace::new();
        for theta in [[0.3, -0.2, 0.1], [3.0, 2.0, -1.0], [-0.5, 0.25, 0.0]] {
            let z = law.solve(&theta).unwrap();
            let exact = t.solve_with(&theta, Start::Cold, 30, &mut ws).unwrap();
            for (a, b) in z.iter().zip(exact.iter()) {
                assert!((a - b).abs() < 1e-3, "{a} vs {b}");
            }
        }
    }

    /// A deadline that expires after `k` checks, every `S` iterations (a
    /// fake clock).
    struct After<const S: u16 = 1> {
        k: u16,
        calls: u16,
    }
    impl<const S: u16> Deadline for After<S> {
        const STRIDE: u16 = S;
        fn expired(&mut self) -> bool {
            if self.calls >= self.k {
                return true;
            }
            self.calls += 1;
            false
        }
    }

    #[test]
    fn a_deadline_with_a_stride_is_asked_every_stride_iterations() {
        let t = tables();
        let mut law = Fgm16Law::<f64, 2, 3, 1, 2>::new(t, m16(), [6554], 2, false, 10).unwrap();
        let theta = [3.0, 2.0, -1.0];
        // Asked before iterations 0, 4, 8: expiring at the m-th question
        // stops after 4 m iterations (at most the 10).
        for (m, run) in [(0, 0), (1, 4), (2, 8), (3, 10), (9, 10)] {
            let mut d = After::<4> { k: m, calls: 0 };
            law.solve_until(&theta, &mut d).unwrap();
            assert_eq!(law.iterations(), run, "m = {m}");
            assert_eq!(d.calls, m.min(3), "questions asked");
        }
    }

    #[test]
    fn a_deadline_stops_the_iterations_with_an_input_in_the_box() {
        let t = tables();
        let new = |k| Fgm16Law::<f64, 2, 3, 1, 2>::new(t, m16(), [6554], 2, false, k).unwrap();
        let thetas = [[0.3, -0.2, 0.1], [3.0, 2.0, -1.0], [-0.5, 0.25, 0.0]];
        for theta in thetas {
            let mut law = new(30);
            let full = law.solve(&theta).unwrap();
            assert_eq!((law.iterations(), law.truncated()), (30, false));
            // A deadline that never expires: bit for bit the same.
            let never = law.solve_until(&theta, &mut After::<1> { k: 99, calls: 0 });
            assert_eq!(never.unwrap().map(f64::to_bits), full.map(f64::to_bits));
            assert_eq!(law.iterations(), 30);
            for k in 0..30u16 {
                let z = law
                    .solve_until(&theta, &mut After::<1> { k, calls: 0 })
                    .unwrap();
                assert_eq!(law.iterations(), k, "stopped after {k} iterations");
                assert!(law.truncated());
                assert_eq!(law.certified_iterations(), 30);
                // In the box: |z_i| <= d_i (the box is [-1, 1] scaled).
                for (zi, di) in z.iter().zip(t.d) {
                    assert!(zi.abs() <= di, "{zi} outside +-{di}");
                }
                // The same as a law made with k iterations.
                if k > 0 {
                    let zk = new(k).solve(&theta).unwrap();
                    assert_eq!(z.map(f64::to_bits), zk.map(f64::to_bits), "k = {k}");
                }
            }
            // The whole law through the wrapper.
            let mut timed = Fgm16Deadline {
                law: new(30),
                deadline: After::<1> { k: 4, calls: 0 },
            };
            let mut u = [0.0; 2];
            timed.control(&theta[..2], &theta[2..], &mut u).unwrap();
            assert_eq!(
                (timed.iterations(), timed.nx(), timed.nr(), timed.nu()),
                (4, 2, 1, 2)
            );
            assert_eq!(u, new(4).solve(&theta).unwrap());
            timed.restart();
        }
    }

    #[test]
    fn refuses_bad_input() {
        let t = tables();
        assert!(Fgm16Law::<f64, 2, 3, 1, 3>::new(t, m16(), [0], 2, false, 3).is_err());
        assert!(Fgm16Law::<f64, 2, 3, 1, 1>::new(t, m16(), [0], 4, false, 3).is_err());
        assert!(Fgm16Law::<f64, 2, 3, 1, 1>::new(t, m16(), [0], 2, false, 0).is_err());
        let mut bad = t;
        bad.k0[0] = f64::NAN;
        assert_eq!(
            Fgm16Law::<f64, 2, 3, 1, 1>::new(bad, m16(), [0], 2, false, 3).unwrap_err(),
            Error::NonFinite
        );
        let mut law = Fgm16Law::<f64, 2, 3, 1, 1>::new(t, m16(), [0], 2, true, 3).unwrap();
        let mut u = [0.0];
        assert_eq!(
            law.control(&[f64::NAN, 0.0], &[0.0], &mut u),
            Err(Error::NonFinite)
        );
        assert!(law.control(&[0.0], &[0.0], &mut u).is_err());
        let mut empty = t;
        empty.lo0 = [2.0, -1.0];
        let mut law = Fgm16Law::<f64, 2, 3, 1, 1>::new(empty, m16(), [0], 2, false, 3).unwrap();
        assert_eq!(
            law.control(&[0.0, 0.0], &[0.0], &mut u),
            Err(Error::Infeasible)
        );
        // Warm start converges to the same point; restart forgets it.
        let mut warm = Fgm16Law::<f64, 2, 3, 1, 2>::new(t, m16(), [6554], 2, true, 30).unwrap();
        let mut cold = Fgm16Law::<f64, 2, 3, 1, 2>::new(t, m16(), [6554], 2, false, 30).unwrap();
        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
        for _ in 0..3 {
            warm.control(&[0.3, -0.2], &[0.1], &mut a).unwrap();
            cold.control(&[0.3, -0.2], &[0.1], &mut b).unwrap();
        }
        assert!((a[0] - b[0]).abs() < 1e-3 && (a[1] - b[1]).abs() < 1e-3);
        warm.restart();
        assert_eq!(warm.iterations(), 30);
    }
}
