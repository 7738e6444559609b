//! An input-rate limit: a double integrator (position and velocity, the
//! input an acceleration) driven to a new position with `|u| <= 1` and
//! `|u_k - u_{k-1}| <= 0.05` per step, the moves also weighted. The law
//! remembers the input it applied last; that is the previous input the
//! first move is measured from.
//!
//! `cargo run -p kestrel-mpc --example rate_limit`
//!
//! The closed loop checks every step against both limits and that the
//! position settles at the reference.
#![allow(dead_code)] // tests/tests/mpc_examples.rs includes this file as a module

use kestrel_core::{ControlLaw, DiscreteLinearModel, Matrix, StateSpace};
use kestrel_mpc::{
    Bounds, MpcError, MpcLaw, MpcProblem, MpcSettings, QpSettings, Terminal, Weight,
};
use nalgebra::dvector;

/// The input (acceleration) bound.
pub const U_MAX: f64 = 1.0;
/// The input-rate bound, per sample.
pub const DU_MAX: f64 = 0.05;

/// What the closed loop did.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Samples simulated.
    pub steps: usize,
    /// The largest `|u_k - u_{k-1}|` applied.
    pub max_du: f64,
    /// The largest `|u_k|` applied.
    pub max_u: f64,
    /// The first sample from which the position stays within 1% of the reference.
    pub settled_at: Option<usize>,
    /// `|y - r|` at the end.
    pub final_error: f64,
}

/// Drives the double integrator from rest at 0 to `reference` for `steps`
/// samples of 0.1 s, checking the limits at every sample.
///
/// # Errors
/// An [`MpcError`] when the problem cannot be built or a QP fails.
pub fn run(reference: f64, steps: usize) -> Result<Summary, MpcError> {
    let model = StateSpace::new(
        Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
        Matrix::from_rows([[0.005], [0.1]]),
        Matrix::from_rows([[1.0, 0.0]]),
        Matrix::from_rows([[0.0]]),
        0.1,
    );
    let settings = MpcSettings {
        horizon: 30,
        q1: Weight::Scalar(1.0),
        q2: Weight::Scalar(1e-3),
        du_weight: Some(Weight::Scalar(1.0)),
        input_bounds: Some(Bounds::new(dvector![-U_MAX], dvector![U_MAX])),
        du_bounds: Some(Bounds::new(dvector![-DU_MAX], dvector![DU_MAX])),
        terminal: Terminal::Lq,
        ..MpcSettings::default()
    };
    let problem = MpcProblem::build(&model, &settings)?;
    let mut law = MpcLaw::clarabel(&problem, QpSettings::default())?;
    let (mut x, mut next, mut u) = ([0.0; 2], [0.0; 2], [0.0]);
    let mut summary = Summary {
        steps,
        max_du: 0.0,
        max_u: 0.0,
        settled_at: None,
        final_error: f64::INFINITY,
    };
    let mut u_prev = 0.0;
    for k in 0..steps {
        law.control(&x, &[reference], &mut u)?;
        let du = u[0] - u_prev;
        assert!(du.abs() <= DU_MAX + 1e-9, "step {k}: |du| = {du}");
        assert!(u[0].abs() <= U_MAX + 1e-9, "step {k}: |u| = {}", u[0]);
        summary.max_du = summary.max_du.max(du.abs());
        summary.max_u = summary.max_u.max(u[0].abs());
        u_prev = u[0];
        model.step_into(&x, &u, &mut next)?;
        x = next;
        let error = (x[0] - reference).abs();
        if error > 0.01 * reference.abs() {
            summary.settled_at = None;
        } else if summary.settled_at.is_none() {
            summary.settled_at = Some(k + 1);
        }
        summary.final_error = error;
    }
    Ok(summary)
}

fn main() -> Result<(), MpcError> {
    let s = run(1.0, 200)?;
    println!(
        "double integrator to 1.0 in {} samples: max |du| {:.4} (limit {DU_MAX}), max |u| {:.4} \
         (limit {U_MAX}), settled within 1% at sample {:?}, final error {:.2e}",
        s.steps, s.max_du, s.max_u, s.settled_at, s.final_error
    );
    Ok(())
}
