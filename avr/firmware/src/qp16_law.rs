//! The exact MPC law of the `qp16` builds: kestrel-avr-rt's fixed-point
//! dual active-set solver (`kestrel_avr_rt::qp16`: kestrel-qp's decision
//! rules on Q15.16 tables) on the thesis-sized box QP of
//! `src/generated_qp16.rs`, solved every period from a cold start (the
//! empty active set) with the iteration cap of the tables: the certified
//! cold worst case (6 for the thesis-sized problem; a warm start from the
//! previous period's set has the larger certified worst case, 8, so a
//! bounded period starts cold). Two kernels with the same iterations:
//! [`Kernel::Sets`] (`Qp16SetSolver`: a precomputed `M_A^-1` per active
//! set, the `qp16` builds) and [`Kernel::Ldl`] (`Qp16Solver`: the LDL'
//! factor updated on every change, feature `qp16-ldl`).
//!
//! Each period: `theta = [x; r]` in Q15.16 (read in place for `Q16Mac`,
//! converted for f32), one cold solve, the first move out in the loop's
//! scalar. On any solver error (iteration cap, a singular active set,
//! crossing bounds) the law answers the solver's fallback (the
//! unconstrained optimum clamped to the period's box,
//! `Qp16Solver::fallback`) and sets [`FALLBACK`] in
//! [`LawInfo::iterations`]; a non-finite parameter is an error for the
//! loop's failsafe.

use kestrel_avr_rt::control::LawInfo;
use kestrel_avr_rt::output::RtScalar;
use kestrel_avr_rt::qp16::{
    Qp16Error, Qp16Info, Qp16SetSolver, Qp16SetTables, Qp16Solver, Qp16Start, Qp16Tables,
};
use kestrel_core::{ControlLaw, Error, check_len};

/// Set in [`LawInfo::iterations`] when the period's input is the fallback
/// (as `qp_law::FALLBACK`); the low bits are then the iteration cap.
pub const FALLBACK: u16 = 0x8000;

/// The solver kernel.
pub enum Kernel<'t, const N: usize, const SETS: usize, const E: usize> {
    /// The LDL' factor of the active set updated on every change.
    Ldl(Qp16Solver<N>),
    /// A precomputed inverse per active set (no factor, no division).
    Sets(Qp16SetSolver<N>, &'t Qp16SetTables<N, SETS, E>),
}

impl<const N: usize, const SETS: usize, const E: usize> Kernel<'_, N, SETS, E> {
    fn solve<const P: usize>(
        &mut self,
        t: &Qp16Tables<N, P>,
        theta: &[i32; P],
        start: Qp16Start,
    ) -> Result<Qp16Info, Qp16Error> {
        match self {
            Kernel::Ldl(s) => s.solve(t, theta, start),
            Kernel::Sets(s, sets) => s.solve(t, sets, theta, start),
        }
    }
    fn solution(&self) -> [i32; N] {
        match self {
            Kernel::Ldl(s) => *s.solution(),
            Kernel::Sets(s, _) => *s.solution(),
        }
    }
    fn fallback(&self) -> [i32; N] {
        match self {
            Kernel::Ldl(s) => s.fallback(),
            Kernel::Sets(s, _) => s.fallback(),
        }
    }
    fn reset(&mut self) {
        match self {
            Kernel::Ldl(s) => s.reset(),
            Kernel::Sets(s, _) => s.reset(),
        }
    }
}

/// The fixed-point solver as the loop's [`ControlLaw`]: `N` variables, `P
/// = nx + nr` parameters, `NU` outputs (the first move), scalar `S`.
pub struct Qp16Law<
    't,
    S,
    const N: usize,
    const P: usize,
    const NU: usize,
    const SETS: usize,
    const E: usize,
> {
    tables: &'t Qp16Tables<N, P>,
    solver: Kernel<'t, N, SETS, E>,
    nx: usize,
    iterations: u16,
    _scalar: core::marker::PhantomData<S>,
}

impl<
    't,
    S: RtScalar,
    const N: usize,
    const P: usize,
    const NU: usize,
    const SETS: usize,
    const E: usize,
> Qp16Law<'t, S, N, P, NU, SETS, E>
{
    /// The law on `tables` with the solver `kernel`, reading `nx` states.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `nx > P` or `NU > N`.
    pub fn new(
        tables: &'t Qp16Tables<N, P>,
        kernel: Kernel<'t, N, SETS, E>,
        nx: usize,
    ) -> Result<Self, Error> {
        for (found, limit) in [(nx, P), (NU, N)] {
            if found > limit {
                return Err(Error::DimensionMismatch {
                    expected: limit,
                    found,
                });
            }
        }
        Ok(Qp16Law {
            tables,
            solver: kernel,
            nx,
            iterations: 0,
            _scalar: core::marker::PhantomData,
        })
    }
}

/// `w 2^s` (raw Q15.16 of `z`), saturated; `s` the tables' variable shift.
#[inline(never)]
fn unscale(w: i32, s: i8) -> i32 {
    if s == 0 {
        return w; // the thesis-sized tables: no 64-bit shift
    }
    let v = if s >= 0 {
        i64::from(w) << s.min(31)
    } else {
        let k = (-i32::from(s)).min(62) as u32;
        (i64::from(w) + (1i64 << (k - 1))) >> k
    };
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

impl<
    S: RtScalar,
    const N: usize,
    const P: usize,
    const NU: usize,
    const SETS: usize,
    const E: usize,
> ControlLaw for Qp16Law<'_, S, N, P, NU, SETS, E>
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
        let mut theta = [0i32; P];
        let (tx, tr) = theta.split_at_mut(self.nx);
        S::to_q16_all(x, tx).ok_or(Error::NonFinite)?;
        S::to_q16_all(r, tr).ok_or(Error::NonFinite)?;
        let w = match self.solver.solve(self.tables, &theta, Qp16Start::Cold) {
            Ok(info) => {
                self.iterations = info.iterations.min(!FALLBACK);
                self.solver.solution()
            }
            Err(_) => {
                self.iterations = FALLBACK | self.tables.max_iterations.min(!FALLBACK);
                self.solver.fallback()
            }
        };
        for (ui, &wi) in u.iter_mut().zip(&w) {
            *ui = S::from_q16(unscale(wi, self.tables.var_shift));
        }
        Ok(())
    }
}

impl<
    S: RtScalar,
    const N: usize,
    const P: usize,
    const NU: usize,
    const SETS: usize,
    const E: usize,
> LawInfo for Qp16Law<'_, S, N, P, NU, SETS, E>
{
    fn iterations(&self) -> u16 {
        self.iterations
    }
    fn restart(&mut self) {
        // Every period starts cold already; forget the last set anyway.
        self.solver.reset();
    }
}

/// The `qp16` builds' solver kernel: the per-set tables of
/// `src/generated_qp16.rs`, or with `qp16-ldl` the factor updates.
pub fn kernel() -> Kernel<'static, 4, 16, 128> {
    if cfg!(feature = "qp16-ldl") {
        Kernel::Ldl(Qp16Solver::new())
    } else {
        Kernel::Sets(Qp16SetSolver::new(), &crate::generated_qp16::QP16_SETS)
    }
}
