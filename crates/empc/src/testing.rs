//! Test and benchmark problems: small condensed MPC problems in the thesis form.
//!
//! These are deliberately simple (a stable random system, output tracking
//! with a constant reference, box-bounded inputs, optional move blocking
//! and a parameter that shifts some input bounds, as the thesis's throttle
//! does in its (6.7)).
//! The condensing is kestrel-mpc's ([`MpcProblem::build`], then
//! [`MpcProblem::to_mpqp`]); this module only chooses the data and applies
//! two rewrites of the resulting `kestrel.mpqp.v1` problem:
//!
//! - the input bounds are written once per step of the horizon, as in the
//!   thesis's (6.26b), instead of once per move-blocking block: a block of
//!   `L` steps then has `L` exactly coincident copies of its rows, a
//!   deliberate degeneracy for the mpQP solver;
//! - a problem without outputs (`ny = 0`) regulates the state: it is built
//!   as tracking of `y = x`, and the reference parameters are then fixed at
//!   zero and removed from `theta`.

pub use crate::rng::Rng;
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_mpc::{Blocking, Bounds, MpcProblem, MpcSettings, Parameter, Terminal, Weight};
use nalgebra::{DMatrix, DVector};

/// A tracking MPC problem to condense.
#[derive(Clone, Debug)]
pub struct MpcSpec {
    /// State matrix `nx x nx`.
    pub a: DMatrix<f64>,
    /// Input matrix `nx x nu`.
    pub b: DMatrix<f64>,
    /// Output matrix `ny x nx`; `ny = 0` means regulation of the state without references.
    pub c: DMatrix<f64>,
    /// Output (or state) weight, a scalar times identity.
    pub q: f64,
    /// Input weight, a scalar times identity.
    pub r: f64,
    /// Prediction horizon `N`.
    pub horizon: usize,
    /// Number of free moves `Ns` (the input is held after `Ns` steps).
    pub free_moves: usize,
    /// Input lower bounds (`nu`).
    pub u_lo: Vec<f64>,
    /// Input upper bounds (`nu`).
    pub u_hi: Vec<f64>,
    /// Inputs whose bounds move by -1 per unit of the shift parameter (the
    /// last entry of `theta`, as the thesis's throttle in (6.7)); empty: no
    /// shift parameter.
    pub shifted_inputs: Vec<usize>,
    /// Range of the shift parameter.
    pub shift_range: (f64, f64),
    /// Symmetric bound of every state parameter.
    pub x_bound: f64,
    /// Symmetric bound of every reference parameter.
    pub ref_bound: f64,
}

/// A random stable system: `A` scaled to spectral norm `rho`, random `B`, `C`.
pub fn random_system(nx: usize, nu: usize, ny: usize, rho: f64, seed: u64) -> MpcSpec {
    let mut rng = Rng::new(seed);
    let mut a = DMatrix::from_fn(nx, nx, |_, _| rng.sym());
    let s = a.clone().svd(false, false).singular_values.max().max(1e-12);
    a *= rho / s;
    let b = DMatrix::from_fn(nx, nu, |_, _| rng.sym());
    let c = DMatrix::from_fn(ny, nx, |_, _| rng.sym());
    MpcSpec {
        a,
        b,
        c,
        q: 1.0,
        r: 0.1,
        horizon: 2,
        free_moves: 2,
        u_lo: vec![-1.0; nu],
        u_hi: vec![1.0; nu],
        shifted_inputs: Vec::new(),
        shift_range: (0.0, 0.0),
        x_bound: 2.0,
        ref_bound: 1.0,
    }
}

impl MpcSpec {
    /// Condenses into `kestrel.mpqp.v1` with kestrel-mpc: `theta = [x; r;
    /// shift]`, `z` = the `Ns` free moves, the cost
    /// `sum_{j=1..N} q/2 |y_j - r|^2 + sum_{k=0..N-1} r/2 |u_k|^2`
    /// ([`Terminal::StageWeight`]), the bounds written once per step (see
    /// the module documentation).
    ///
    /// # Panics
    /// If kestrel-mpc rejects the data (non-finite matrices, `u_lo > u_hi`,
    /// non-positive `r` with an output weight that misses an input
    /// direction, ...): these are test problems.
    pub fn condense(&self) -> MpqpProblem {
        let (nx, nu) = (self.a.nrows(), self.b.ncols());
        let regulate = self.c.nrows() == 0;
        let c = if regulate {
            DMatrix::identity(nx, nx)
        } else {
            self.c.clone()
        };
        let d = DMatrix::zeros(c.nrows(), nu);
        // The sample time does not enter the condensed QP; any ts > 0 is a
        // discrete-time model.
        let model = SsModel::new(1.0, self.a.clone(), self.b.clone(), c, d)
            .expect("MpcSpec: A, B, C must be finite and of matching sizes");
        let mut bounds = Bounds::new(
            DVector::from_column_slice(&self.u_lo),
            DVector::from_column_slice(&self.u_hi),
        );
        let mut parameters = Vec::new();
        if !self.shifted_inputs.is_empty() {
            // (6.7): the bounds of a shifted input move by -1 per unit shift.
            let coupling = DMatrix::from_fn(nu, 1, |i, _| {
                if self.shifted_inputs.contains(&i) {
                    -1.0
                } else {
                    0.0
                }
            });
            bounds = bounds.shifted(coupling);
            parameters.push(Parameter::new(
                "shift",
                self.shift_range.0,
                self.shift_range.1,
            ));
        }
        let horizon = self.horizon.max(1);
        let settings = MpcSettings {
            horizon,
            blocking: Some(
                Blocking::control_horizon(horizon, self.free_moves.clamp(1, horizon))
                    .expect("1 <= Ns <= N by the clamp"),
            ),
            q1: Weight::Scalar(self.q),
            q2: Weight::Scalar(self.r),
            terminal: Terminal::StageWeight,
            state_bound: self.x_bound,
            reference_bound: self.ref_bound,
            input_bounds: Some(bounds),
            parameters,
            ..MpcSettings::default()
        };
        let problem = MpcProblem::build(&model, &settings)
            .unwrap_or_else(|e| panic!("MpcSpec: kestrel-mpc rejects the test problem: {e}"));
        let mut mpqp = bounds_per_step(&problem);
        if regulate {
            fix_parameters_at_zero(&mut mpqp, problem.layout.nx, problem.layout.ny);
        }
        mpqp
    }
}

/// `problem.to_mpqp()` with the bound rows of each move-blocking block
/// repeated for every step the block covers, in the order of (6.26b): the
/// upper bounds of steps `0..N`, then the lower bounds of steps `0..N`.
/// Only rows are copied; `H` and `F` are kestrel-mpc's.
fn bounds_per_step(problem: &MpcProblem) -> MpqpProblem {
    let mut mpqp = problem.to_mpqp();
    let (nu, n) = (problem.nu, problem.n());
    let steps = Blocking::new(problem.blocks.clone())
        .expect("kestrel-mpc's blocks are valid")
        .block_of_step();
    // Row of kestrel-mpc's per-block constraints for each per-step row.
    let rows: Vec<usize> = [0, n]
        .into_iter()
        .flat_map(|half| {
            steps
                .iter()
                .flat_map(move |&block| (0..nu).map(move |i| half + block * nu + i))
        })
        .collect();
    mpqp.g = mpqp.g.select_rows(&rows);
    mpqp.w = mpqp.w.select_rows(&rows);
    mpqp.e = mpqp.e.select_rows(&rows);
    mpqp
}

/// Restricts `mpqp` to parameters `theta[start..start + len] = 0`: removes
/// those entries of `theta` (rows of `F`, columns of `E`, the box entries).
fn fix_parameters_at_zero(mpqp: &mut MpqpProblem, start: usize, len: usize) {
    let keep: Vec<usize> = (0..mpqp.p())
        .filter(|i| !(start..start + len).contains(i))
        .collect();
    mpqp.f_theta = mpqp.f_theta.select_rows(&keep);
    mpqp.e = mpqp.e.select_columns(&keep);
    mpqp.theta_lb = mpqp.theta_lb.select_rows(&keep);
    mpqp.theta_ub = mpqp.theta_ub.select_rows(&keep);
}

/// A thesis-sized problem: 5 states, 4 inputs, 3 tracked outputs, a
/// shift parameter moving the bounds of inputs 0..3 (as the thesis's
/// throttle), `N = 2`, `Ns = 1`: 9 parameters, 4 variables (scaled units:
/// inputs in [-1, 1] around the shift, the shift in [-0.3, 0.3]).
pub fn thesis_sized(seed: u64) -> MpqpProblem {
    let mut s = random_system(5, 4, 3, 0.95, seed);
    s.horizon = 2;
    s.free_moves = 1;
    s.shifted_inputs = vec![0, 1, 2];
    s.shift_range = (-0.3, 0.3);
    s.x_bound = 1.0;
    s.ref_bound = 1.0;
    s.condense()
}

/// [`thesis_sized`]'s system with horizon `horizon` and `free_moves`
/// free moves (blocks `[1, .., 1, horizon - free_moves + 1]`): `4
/// free_moves` variables, 9 parameters, the states in `[-2, 2]` and the
/// references in `[-1, 1]` ([`random_system`]'s box). The problems of the
/// explicit-MPC-at-scale measurements (BENCHMARKS.md): `N = 5`, `Ns = 2`
/// (blocks `[1, 4]`) and `N = 3`, `Ns = 2` (`[1, 2]`) give about a
/// thousand regions, `Ns = 3` about ten thousand.
pub fn scaled_thesis(seed: u64, horizon: usize, free_moves: usize) -> MpqpProblem {
    let mut s = random_system(5, 4, 3, 0.95, seed);
    s.horizon = horizon;
    s.free_moves = free_moves;
    s.shifted_inputs = vec![0, 1, 2];
    s.shift_range = (-0.3, 0.3);
    s.condense()
}

/// The benchmark problem: 9 parameters (9 states), 8 variables (2 inputs,
/// 4 free moves, horizon 6 with move blocking), about a thousand regions.
pub fn benchmark_9x8() -> MpqpProblem {
    let mut s = random_system(9, 2, 0, 0.98, 7);
    s.horizon = 6;
    s.free_moves = 4;
    s.q = 1.0;
    s.r = 0.05;
    s.x_bound = 20.0;
    s.condense()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocked_bounds_are_coincident_rows_over_the_whole_horizon() {
        // N = 6, Ns = 3: blocks [1, 1, 4], so the last block's rows appear 4 times.
        let mut s = random_system(2, 2, 1, 0.9, 7);
        s.horizon = 6;
        s.free_moves = 3;
        s.shifted_inputs = vec![1];
        s.shift_range = (-0.2, 0.2);
        let p = s.condense();
        assert_eq!((p.n(), p.m(), p.p()), (6, 2 * 6 * 2, 2 + 1 + 1));
        p.validate().unwrap();
        let half = 6 * 2;
        for k in 2..6 {
            for i in 0..2 {
                for off in [0, half] {
                    let (r, r0) = (off + k * 2 + i, off + 2 * 2 + i);
                    assert_eq!(p.g.row(r), p.g.row(r0));
                    assert_eq!(p.w[r], p.w[r0]);
                    assert_eq!(p.e.row(r), p.e.row(r0));
                }
            }
        }
        // Upper rows select +z, lower rows -z; the shift moves input 1 only.
        assert_eq!(p.g[(half - 1, 5)], 1.0);
        assert_eq!(p.g[(2 * half - 1, 5)], -1.0);
        assert_eq!(
            (p.e[(0, 3)], p.e[(1, 3)], p.e[(half + 1, 3)]),
            (0.0, -1.0, 1.0)
        );
        assert_eq!((p.theta_lb[3], p.theta_ub[3]), (-0.2, 0.2));
    }

    #[test]
    fn regulation_has_no_reference_parameters() {
        let p = benchmark_9x8();
        assert_eq!((p.p(), p.n(), p.m()), (9, 8, 2 * 6 * 2));
        p.validate().unwrap();
        assert_eq!(p.e.amax(), 0.0);
        assert!(
            p.theta_lb
                .iter()
                .chain(p.theta_ub.iter())
                .all(|v| v.abs() == 20.0)
        );
        // The state rows of F are kestrel-mpc's tracking problem's with y = x.
        let mut s = random_system(9, 2, 0, 0.98, 7);
        s.c = DMatrix::identity(9, 9);
        s.horizon = 6;
        s.free_moves = 4;
        s.r = 0.05;
        s.x_bound = 20.0;
        let tracking = s.condense();
        assert_eq!(tracking.p(), 18);
        assert_eq!(tracking.h, p.h);
        assert_eq!(tracking.f_theta.rows(0, 9), p.f_theta);
    }
}
