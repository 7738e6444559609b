//! Where the mpQP solution (and so the search tree, which equals the
//! solution's region lookup) and clarabel differ by more than 1e-8, which
//! of the two is the optimum: both answers' objective values and
//! constraint violations at the parameters `whole_box` compares (same
//! seed, every `every`-th of `samples`):
//!
//! `cargo run --release -p kestrel-empc --example clarabel_check --
//! problem.json [first_move] [samples] [every]`
//!
//! The QP is strictly convex, so a feasible point with a lower objective
//! than clarabel's is closer to the unique optimum: where the region law is
//! feasible and its objective is not above clarabel's, clarabel stopped
//! short (its tolerances, ill-conditioning), not the explicit law.

#[path = "../tests/common/mod.rs"]
mod common;
mod shared;

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::{Settings, solve};
use nalgebra::DVector;
use shared::SweepArgs;

fn main() {
    let mut args = std::env::args().skip(1);
    let SweepArgs {
        path,
        first_move: k,
        samples,
        every,
    } = SweepArgs::read(&mut args);
    let prob = MpqpProblem::read(std::path::Path::new(&path)).expect("problem");
    let sol = solve(&prob, &Settings::default()).expect("solve");
    // The sequence of `whole_box`.
    let thetas = common::box_samples(
        prob.theta_lb.as_slice(),
        prob.theta_ub.as_slice(),
        samples,
        2026,
    );
    let (mut n, mut differ, mut law_better, mut failed) = (0, 0, 0, 0);
    let (mut worst_gap, mut worst_viol) = (f64::NEG_INFINITY, 0.0_f64);
    for (i, th) in thetas.iter().enumerate() {
        if every == 0 || i % every != 0 {
            continue;
        }
        n += 1;
        let Some(r) = sol.locate(th, 1e-9) else {
            continue;
        };
        let z = sol.regions[r].z(th);
        let x = match common::clarabel_qp_checked(&prob, th) {
            Ok(Some(x)) => DVector::from_vec(x),
            _ => {
                failed += 1;
                continue;
            }
        };
        let d = (0..k)
            .map(|j| (z[j] - x[j]).abs() / (1.0 + z[j].abs()))
            .fold(0.0, f64::max);
        if d <= 1e-8 {
            continue;
        }
        differ += 1;
        let ((jz, vz), (jx, vx)) = (
            common::objective_and_violation(&prob, th, z.as_slice()),
            common::objective_and_violation(&prob, th, x.as_slice()),
        );
        worst_viol = worst_viol.max(vz);
        // Objective gap of the law over clarabel, relative to |J|.
        let gap = (jz - jx) / (1.0 + jx.abs());
        worst_gap = worst_gap.max(gap);
        if common::law_at_least_as_good(&prob, th, z.as_slice(), x.as_slice()) {
            law_better += 1;
        }
        println!(
            "theta {i}: first move differs by {d:.1e}; law J {jz:.9e} (violation {vz:.1e}), clarabel J {jx:.9e} (violation {vx:.1e})"
        );
    }
    println!(
        "{path}: {n} parameters, {differ} differ from clarabel by more than 1e-8; at {law_better} of them the law is feasible with an objective not above clarabel's (worst relative objective gap law - clarabel {worst_gap:.1e}, worst law violation {worst_viol:.1e}); clarabel did not converge at {failed}"
    );
}
