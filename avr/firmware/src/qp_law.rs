//! The exact MPC law of the `qp` builds: kestrel-qp's dual active-set
//! solver on the thesis-sized box QP (`src/generated_qp.rs`), solved to
//! its optimum every period, warm-started from the previous period's
//! active set.
//!
//! Each period: `theta = [x; r]`, the linear term `q = F theta + f0` and
//! the box `lo = LO theta + lo0`, `hi = HI theta + hi0` (zero entries of
//! the maps skipped: 38 of 108 terms are non-zero here), one solve, the
//! first move `z[..NU]` out.
//!
//! Errors:
//! - the solver's [`QpError::IterationLimit`] and [`QpError::Infeasible`]
//!   (the iteration cap reached, or no solution): the law answers the
//!   **fallback**, the unconstrained optimum `-H^-1 q` clamped to this
//!   period's box (the clipped unconstrained law: feedback on this
//!   period's state, a bounded input in this period's box, as
//!   `kestrel_avr_rt::qp16::Qp16Solver::fallback`), and reports it by
//!   [`FALLBACK`] in [`LawInfo::iterations`]; the next period starts cold;
//! - any other error (a non-finite parameter, crossing bounds, wrong
//!   sizes): the law returns it and the loop applies its safe pulses
//!   (`kestrel_avr_rt::control::RateLoop`).
//!
//! Generic over the solver's scalar: the firmware runs it in f32, the HIL
//! test's host reference (`crates/tricopter/tests/hil`) includes this file
//! and runs it in f64.

use kestrel_avr_rt::control::LawInfo;
use kestrel_core::{ControlLaw, Error, check_len};
use kestrel_qp::{QpData, QpError, QpScalar, QpSolver, Start};

/// Set in [`LawInfo::iterations`] when the period's input is the fallback
/// (the solver stopped at its iteration cap or found no solution); the low
/// bits are then the iterations made before it stopped.
pub const FALLBACK: u16 = 0x8000;

/// The box QP's parameter maps (rows per variable, `theta` columns).
#[derive(Clone, Copy, Debug)]
pub struct QpMaps<'a, S, const N: usize, const P: usize> {
    /// Linear term map `F`.
    pub f: &'a [[S; P]; N],
    /// Linear term constant `f0`.
    pub f0: &'a [S; N],
    /// Lower bound map `LO`.
    pub lo: &'a [[S; P]; N],
    /// Lower bound constant `lo0`.
    pub lo0: &'a [S; N],
    /// Upper bound map `HI`.
    pub hi: &'a [[S; P]; N],
    /// Upper bound constant `hi0`.
    pub hi0: &'a [S; N],
    /// `H^-1`, for the fallback's unconstrained optimum.
    pub hinv: &'a [[S; N]; N],
}

/// Bit `j` set where `row[j]` is not zero (`P <= 16`).
fn mask<S: QpScalar, const P: usize>(row: &[S; P]) -> u16 {
    row.iter()
        .enumerate()
        .fold(0, |m, (j, v)| if *v != S::ZERO { m | 1 << j } else { m })
}

/// `c + row' theta` over the non-zero entries of `row` (`mask`).
#[inline(always)]
fn affine<S: QpScalar, const P: usize>(row: &[S; P], mask: u16, c: S, theta: &[S; P]) -> S {
    let mut acc = c;
    for j in 0..P {
        if mask & (1 << j) != 0 {
            acc = acc.mul_add(row[j], theta[j]);
        }
    }
    acc
}

/// kestrel-qp's solver as the loop's [`ControlLaw`]: `N` variables, `P =
/// nx + nr` parameters, `NU` outputs (the first move).
pub struct QpLaw<'w, S, const N: usize, const P: usize, const NU: usize> {
    solver: QpSolver<'w, S>,
    maps: QpMaps<'w, S, N, P>,
    masks: [[u16; N]; 3],
    nx: usize,
    warm_start: bool,
    warm: bool,
    iterations: u16,
    z: [S; N],
    fallbacks: u16,
}

impl<'w, S: QpScalar, const N: usize, const P: usize, const NU: usize> QpLaw<'w, S, N, P, NU> {
    /// The law on a solver set up for the problem's Hessian (no rows of
    /// `G`: `m = 0`), reading `nx` states; with `warm_start` each solve
    /// after a successful one starts from its active set, otherwise every
    /// solve starts cold.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if the solver is not `N x 0`, `nx > P`,
    /// `NU > N` or `P > 16`; [`Error::NonFinite`] for a non-finite map.
    pub fn new(
        solver: QpSolver<'w, S>,
        maps: QpMaps<'w, S, N, P>,
        nx: usize,
        warm_start: bool,
    ) -> Result<Self, Error> {
        let dims = [(solver.n(), N), (solver.m(), 0)];
        if let Some(&(found, expected)) = dims.iter().find(|(a, b)| a != b) {
            return Err(Error::DimensionMismatch { expected, found });
        }
        for (found, limit) in [(nx, P), (NU, N), (P, 16)] {
            if found > limit {
                return Err(Error::DimensionMismatch {
                    expected: limit,
                    found,
                });
            }
        }
        let finite = [maps.f, maps.lo, maps.hi]
            .iter()
            .all(|m| m.iter().flatten().all(|v| v.is_finite()))
            && maps.hinv.iter().flatten().all(|v| v.is_finite())
            && [maps.f0, maps.lo0, maps.hi0]
                .iter()
                .all(|v| v.iter().all(|x| x.is_finite()));
        if !finite {
            return Err(Error::NonFinite);
        }
        let masks = [
            core::array::from_fn(|i| mask(&maps.f[i])),
            core::array::from_fn(|i| mask(&maps.lo[i])),
            core::array::from_fn(|i| mask(&maps.hi[i])),
        ];
        Ok(QpLaw {
            solver,
            maps,
            masks,
            nx,
            warm_start,
            warm: false,
            iterations: 0,
            z: [S::ZERO; N],
            fallbacks: 0,
        })
    }

    /// The whole solution of the last call (all blocked moves), or the
    /// fallback.
    pub fn last_solution(&self) -> &[S; N] {
        &self.z
    }

    /// Periods that answered the fallback since the law was made.
    pub fn fallbacks(&self) -> u16 {
        self.fallbacks
    }

    /// The solver.
    pub fn solver(&self) -> &QpSolver<'w, S> {
        &self.solver
    }

    /// Solves for `theta`; `z` holds the solution or the fallback.
    fn solve(&mut self, theta: &[S; P]) -> Result<(), Error> {
        let m = &self.maps;
        let q: [S; N] = core::array::from_fn(|i| affine(&m.f[i], self.masks[0][i], m.f0[i], theta));
        let lb: [S; N] =
            core::array::from_fn(|i| affine(&m.lo[i], self.masks[1][i], m.lo0[i], theta));
        let ub: [S; N] =
            core::array::from_fn(|i| affine(&m.hi[i], self.masks[2][i], m.hi0[i], theta));
        let data = QpData {
            q: &q,
            l: &[],
            u: &[],
            lb: &lb,
            ub: &ub,
        };
        let start = if self.warm { Start::Warm } else { Start::Cold };
        match self.solver.solve(&data, start) {
            Ok(info) => {
                self.iterations = info.iterations.min(usize::from(!FALLBACK)) as u16;
                self.warm = self.warm_start;
                self.solver.solution(&mut self.z)?;
                Ok(())
            }
            Err(QpError::IterationLimit | QpError::Infeasible) => {
                // The unconstrained optimum -H^-1 q, clamped to the box.
                for (i, zi) in self.z.iter_mut().enumerate() {
                    let unc = -S::dot(&m.hinv[i], &q);
                    *zi = unc.clamp_to(lb[i], ub[i]);
                }
                let cap = self.solver.settings().max_iterations;
                self.iterations = FALLBACK | cap.min(usize::from(!FALLBACK)) as u16;
                self.fallbacks = self.fallbacks.saturating_add(1);
                self.warm = false;
                Ok(())
            }
            Err(e) => {
                self.warm = false;
                Err(e.into())
            }
        }
    }
}

/// `v` within `[lo, hi]` (`lo <= hi`, checked by the solver before).
trait ClampTo: Sized {
    fn clamp_to(self, lo: Self, hi: Self) -> Self;
}
impl<S: QpScalar> ClampTo for S {
    fn clamp_to(self, lo: S, hi: S) -> S {
        if self < lo {
            lo
        } else if self > hi {
            hi
        } else {
            self
        }
    }
}

impl<S: QpScalar, const N: usize, const P: usize, const NU: usize> ControlLaw
    for QpLaw<'_, S, N, P, NU>
{
    type Scalar = S;
    fn nx(&self) -> usize {
        self.nx
    }
    fn nr(&self) -> usize {
        P - self.nx
    }
    fn nu(&self) -> usize {
        NU
    }
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        check_len(x, self.nx)?;
        check_len(r, P - self.nx)?;
        check_len(u, NU)?;
        let theta: [S; P] =
            core::array::from_fn(|j| if j < self.nx { x[j] } else { r[j - self.nx] });
        self.solve(&theta)?;
        u.copy_from_slice(&self.z[..NU]);
        Ok(())
    }
}

impl<S: QpScalar, const N: usize, const P: usize, const NU: usize> LawInfo
    for QpLaw<'_, S, N, P, NU>
{
    fn iterations(&self) -> u16 {
        self.iterations
    }
    fn restart(&mut self) {
        self.warm = false;
        self.z = [S::ZERO; N];
    }
}
