//! Control laws for the rate loop (`control::RateLoop`) built from the
//! no_std parts of the solver crates, and [`LawInfo`], what the loop asks
//! of a law beyond [`ControlLaw`].
//!
//! [`FgmLaw`]: kestrel-fgm's fast gradient method on the condensed MPC
//! problem, `theta = [x; r; throttle]` (kestrel-mpc's layout), applying the
//! first `NU` entries of the solution (the first input move, a deviation
//! from the trim).

use kestrel_core::{ControlLaw, Error, Scalar, all_finite, check_len};
use kestrel_fgm::{FgmTables, FgmWorkspace, Start};

/// What a control law reports beyond [`ControlLaw`]: its work count and a
/// restart hook for recovery after a failsafe.
pub trait LawInfo {
    /// Iterations (fast gradient) or nodes visited (explicit MPC) in the last call.
    fn iterations(&self) -> u16 {
        0
    }
    /// Clears internal memory (warm starts, integrators) after a failsafe.
    fn restart(&mut self) {}
}

/// How each period's solve starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FgmStart {
    /// Cold start with a fixed iteration count (the certified one: the
    /// deterministic worst case).
    Cold,
    /// Warm start from the previous solution, with a fixed iteration count.
    Warm,
}

/// kestrel-fgm's run-time solver as a [`ControlLaw`]: `N` decision
/// variables, `P = nx + nr` parameters, `T` momentum entries, `NU` inputs.
///
/// ```
/// use kestrel_avr_rt::law::{FgmLaw, FgmStart};
/// use kestrel_core::{ControlLaw, Matrix};
/// use kestrel_fgm::FgmTables;
/// // One variable, theta = [x, r]: minimise (z - (r - x))^2 / 2 on [-1, 1]
/// // (M = 0, K = [-1, 1]: one gradient step is exact).
/// let t = FgmTables::<f64, 1, 2, 1> {
///     m: Matrix::from_rows([[0.0]]), k_theta: Matrix::from_rows([[-1.0, 1.0]]), k0: [0.0],
///     lo_theta: Matrix::zeros(), lo0: [-1.0], hi_theta: Matrix::zeros(), hi0: [1.0],
///     d: [1.0], d_inv: [1.0], betas: [0.0], iterations: 3, warm_iterations: 3, shift: 0,
/// };
/// let mut law = FgmLaw::<f64, 1, 2, 1, 1>::new(t, 1, FgmStart::Cold, 3).unwrap();
/// let mut u = [0.0];
/// law.control(&[0.25], &[0.5], &mut u).unwrap();
/// assert!((u[0] - 0.25).abs() < 1e-12);
/// law.control(&[0.0], &[5.0], &mut u).unwrap();
/// assert_eq!(u[0], 1.0); // the box
/// ```
#[derive(Clone, Debug)]
pub struct FgmLaw<S, const N: usize, const P: usize, const T: usize, const NU: usize> {
    tables: FgmTables<S, N, P, T>,
    ws: FgmWorkspace<S, N>,
    nx: usize,
    start: FgmStart,
    iterations: u16,
    last: [S; N],
}

impl<S: Scalar, const N: usize, const P: usize, const T: usize, const NU: usize>
    FgmLaw<S, N, P, T, NU>
{
    /// A law reading `nx` states (the other `P - nx` parameters are the
    /// references and the throttle) and running `iterations` iterations.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] if `nx > P` or `NU > N`;
    /// [`Error::InvalidArgument`] without iterations; [`Error::NonFinite`]
    /// with non-finite tables.
    pub fn new(
        tables: FgmTables<S, N, P, T>,
        nx: usize,
        start: FgmStart,
        iterations: u16,
    ) -> Result<Self, Error> {
        check_law_sizes::<N, P, NU>(nx)?;
        let finite = tables.m.is_finite()
            && tables.k_theta.is_finite()
            && tables.lo_theta.is_finite()
            && tables.hi_theta.is_finite()
            && all_finite(&tables.k0)
            && all_finite(&tables.lo0)
            && all_finite(&tables.hi0)
            && all_finite(&tables.d)
            && all_finite(&tables.d_inv)
            && all_finite(&tables.betas);
        if iterations == 0 {
            return Err(Error::InvalidArgument("fast gradient with zero iterations"));
        }
        if !finite {
            return Err(Error::NonFinite);
        }
        Ok(FgmLaw {
            tables,
            ws: FgmWorkspace::new(),
            nx,
            start,
            iterations,
            last: [S::ZERO; N],
        })
    }

    /// The whole solution of the last call (all blocked moves).
    pub fn last_solution(&self) -> &[S; N] {
        &self.last
    }

    /// The tables.
    pub fn tables(&self) -> &FgmTables<S, N, P, T> {
        &self.tables
    }
}

impl<S: Scalar, const N: usize, const P: usize, const T: usize, const NU: usize> ControlLaw
    for FgmLaw<S, N, P, T, NU>
{
    type Scalar = S;
    crate::law::parametric_law_sizes!();
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        let theta: [S; P] = pack_theta(self.nx, NU, x, r, u)?;
        let k = self.iterations as usize;
        let z = match (self.start, self.ws.previous().copied()) {
            (FgmStart::Warm, Some(prev)) => {
                self.tables
                    .solve_with(&theta, Start::Warm(&prev), k, &mut self.ws)?
            }
            _ => self
                .tables
                .solve_with(&theta, Start::Cold, k, &mut self.ws)?,
        };
        self.last = z;
        u.copy_from_slice(&z[..NU]);
        Ok(())
    }
}

impl<S: Scalar, const N: usize, const P: usize, const T: usize, const NU: usize> LawInfo
    for FgmLaw<S, N, P, T, NU>
{
    fn iterations(&self) -> u16 {
        self.iterations
    }
    fn restart(&mut self) {
        self.ws.reset();
    }
}

/// The `ControlLaw` size methods of a parametric law with a field `nx`
/// and const parameters `P` (parameters: `nx` states, then `P - nx`
/// references) and `NU` (outputs); shared by the laws of this crate.
macro_rules! parametric_law_sizes {
    () => {
        fn nx(&self) -> usize {
            self.nx
        }
        fn nr(&self) -> usize {
            P - self.nx
        }
        fn nu(&self) -> usize {
            NU
        }
    };
}
pub(crate) use parametric_law_sizes;

/// Checks that a parametric law over `N` variables and `P` parameters can
/// read `nx` states from the parameters (`nx <= P`) and write `NU` inputs
/// from the variables (`NU <= N`); shared by the laws of this crate.
pub(crate) fn check_law_sizes<const N: usize, const P: usize, const NU: usize>(
    nx: usize,
) -> Result<(), Error> {
    if nx > P {
        return Err(Error::DimensionMismatch {
            expected: P,
            found: nx,
        });
    }
    if NU > N {
        return Err(Error::DimensionMismatch {
            expected: N,
            found: NU,
        });
    }
    Ok(())
}

/// Checks the lengths of a parametric law's state `x`, reference `r` and
/// output `u` (`r` takes the `P - nx` parameters after the state) and packs
/// `theta = [x; r]`; shared by the laws of this crate.
pub(crate) fn pack_theta<S: Scalar, const P: usize>(
    nx: usize,
    nu: usize,
    x: &[S],
    r: &[S],
    u: &[S],
) -> Result<[S; P], Error> {
    let nr = P.checked_sub(nx).ok_or(Error::DimensionMismatch {
        expected: P,
        found: nx,
    })?;
    check_len(x, nx)?;
    check_len(r, nr)?;
    check_len(u, nu)?;
    let mut theta = [S::ZERO; P];
    let (tx, tr) = theta.split_at_mut(nx);
    tx.copy_from_slice(x);
    tr.copy_from_slice(r);
    Ok(theta)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use kestrel_core::Matrix;

    /// A 2-variable, 3-parameter box QP's tables without scaling (`D = I`),
    /// shared with the 16-bit law's tests ([`crate::fgm16`]).
    pub(crate) fn tables() -> FgmTables<f64, 2, 3, 1> {
        FgmTables {
            m: Matrix::from_rows([[0.5, 0.1], [0.1, 0.4]]),
            k_theta: Matrix::from_rows([[1.0, 0.0, 0.5], [0.0, -1.0, 0.2]]),
            k0: [0.0; 2],
            lo_theta: Matrix::zeros(),
            lo0: [-1.0; 2],
            hi_theta: Matrix::zeros(),
            hi0: [1.0; 2],
            d: [1.0; 2],
            d_inv: [1.0; 2],
            betas: [0.2],
            iterations: 30,
            warm_iterations: 30,
            shift: 0,
        }
    }

    #[test]
    fn law_matches_the_solver_and_checks_dimensions() {
        let t = tables();
        let mut law = FgmLaw::<f64, 2, 3, 1, 1>::new(t, 2, FgmStart::Cold, 30).unwrap();
        let mut u = [0.0];
        law.control(&[0.3, -0.2], &[0.1], &mut u).unwrap();
        let mut ws = FgmWorkspace::new();
        let z = t
            .solve_with(&[0.3, -0.2, 0.1], Start::Cold, 30, &mut ws)
            .unwrap();
        assert_eq!(u[0], z[0]);
        assert_eq!(law.last_solution(), &z);
        assert_eq!(law.iterations(), 30);
        assert!(law.control(&[0.3], &[0.1], &mut u).is_err());
        assert!(law.control(&[0.3, 0.1], &[0.1, 0.2], &mut u).is_err());
        assert_eq!(
            law.control(&[f64::NAN, 0.0], &[0.1], &mut u),
            Err(Error::NonFinite)
        );
        assert!(FgmLaw::<f64, 2, 3, 1, 3>::new(t, 2, FgmStart::Cold, 30).is_err());
        assert!(FgmLaw::<f64, 2, 3, 1, 1>::new(t, 4, FgmStart::Cold, 30).is_err());
        assert!(FgmLaw::<f64, 2, 3, 1, 1>::new(t, 2, FgmStart::Cold, 0).is_err());
        let mut bad = t;
        bad.m.data[0][0] = f64::NAN;
        assert!(FgmLaw::<f64, 2, 3, 1, 1>::new(bad, 2, FgmStart::Cold, 30).is_err());
    }

    #[test]
    fn warm_start_reaches_the_same_solution() {
        let t = tables();
        let mut cold = FgmLaw::<f64, 2, 3, 1, 2>::new(t, 2, FgmStart::Cold, 30).unwrap();
        let mut warm = FgmLaw::<f64, 2, 3, 1, 2>::new(t, 2, FgmStart::Warm, 30).unwrap();
        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
        for k in 0..5 {
            let x = [0.1 * k as f64, -0.05];
            cold.control(&x, &[0.2], &mut a).unwrap();
            warm.control(&x, &[0.2], &mut b).unwrap();
        }
        assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6);
        warm.restart();
        warm.control(&[0.0, 0.0], &[0.0], &mut b).unwrap();
    }
}
