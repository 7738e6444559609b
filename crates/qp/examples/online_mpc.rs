//! Exact online MPC for any plant: a double integrator (position and
//! velocity, the input an acceleration) with `|u| <= 1`, a rate limit
//! `|u_k - u_{k-1}| <= 0.2` (general rows of the QP) and a soft position
//! limit, flown with kestrel-qp's dual active-set solver in the
//! receding-horizon law, cold and warm-started, against clarabel.
//!
//! `cargo run -p kestrel-qp --features mpc --example online_mpc`
//!
//! Prints the active-set changes per step of both starts and the largest
//! difference from clarabel's inputs.

use kestrel_core::{ControlLaw, Matrix, StateSpace};
use kestrel_mpc::{Bounds, MpcLaw, MpcProblem, MpcSettings, SoftPenalty, Terminal, Weight};
use kestrel_qp::{ActiveSetSolver, QpSettings, Start};
use nalgebra::{DVector, dmatrix, dvector};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let model = StateSpace::new(
        Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]),
        Matrix::from_rows([[0.005], [0.1]]),
        Matrix::from_rows([[1.0, 0.0]]),
        Matrix::from_rows([[0.0]]),
        0.1,
    );
    let problem = MpcProblem::build(
        &model,
        &MpcSettings {
            horizon: 20,
            q2: Weight::Scalar(0.01),
            du_weight: Some(Weight::Scalar(0.1)),
            terminal: Terminal::Lq,
            input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
            du_bounds: Some(Bounds::new(dvector![-0.2], dvector![0.2])),
            output_bounds: Some(
                Bounds::new(dvector![f64::NEG_INFINITY], dvector![1.05])
                    .with_soft(SoftPenalty::default()),
            ),
            ..MpcSettings::default()
        },
    )?;
    println!(
        "QP: {} variables, {} constraint rows, {} parameters",
        problem.n(),
        problem.to_mpqp().m(),
        problem.p()
    );
    let mut reference = MpcLaw::clarabel(&problem, kestrel_mpc::QpSettings::default())?;
    let mut cold = ActiveSetSolver::mpc_law(&problem, QpSettings::default(), Start::Cold)?;
    let mut warm = ActiveSetSolver::mpc_law(&problem, QpSettings::default(), Start::Warm)?;
    let (a, b) = (dmatrix![1.0, 0.1; 0.0, 1.0], dmatrix![0.005; 0.1]);
    let mut x = dvector![0.0, 0.0];
    let (mut u, mut u_cold, mut u_warm) = ([0.0], [0.0], [0.0]);
    let mut largest_difference: f64 = 0.0;
    println!("step  position  input    changes (cold, warm)");
    for k in 0..60 {
        let r = if k < 30 { 1.0 } else { 0.0 };
        reference.control(x.as_slice(), &[r], &mut u)?;
        cold.control(x.as_slice(), &[r], &mut u_cold)?;
        warm.control(x.as_slice(), &[r], &mut u_warm)?;
        largest_difference = largest_difference
            .max((u[0] - u_cold[0]).abs())
            .max((u[0] - u_warm[0]).abs());
        if k % 5 == 0 {
            println!(
                "{k:4}  {:8.4}  {:7.4}  {}, {}",
                x[0],
                u_warm[0],
                cold.solver().last_iterations(),
                warm.solver().last_iterations()
            );
        }
        x = &a * &x + &b * DVector::from_column_slice(&u_warm);
    }
    println!(
        "most changes in a step: cold {}, warm {}; largest input difference from clarabel {largest_difference:.1e}",
        cold.solver().worst_iterations(),
        warm.solver().worst_iterations()
    );
    Ok(())
}
