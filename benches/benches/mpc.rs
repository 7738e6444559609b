//! One reference QP solve (clarabel) of the tricopter MPC designed from
//! the identified 5-state model (models/tricopter-blackbox-5.json), for the
//! thesis-sized problem (N = 2, one block, n = 4) and the larger one
//! (N = 10, blocks [1, 1, 2, 6], n = 16): the yardstick the explicit and
//! fast-gradient solvers must beat. Two parameters each: the state of
//! Table 7.2 (rates [0.2, 0.3, 0.4] rad/s, reference 0, hover throttle;
//! no bound active) and the release of 7.7.1 (rates [2, 2, 2] rad/s; the
//! servo bound active).
//!
//! Beside it, the exact online solver at the same parameters: kestrel-qp's
//! `ActiveSetSolver` as kestrel-mpc's law calls it (`solve_into`: fill the
//! data, solve, refine, copy `z`; owned workspaces kept between calls) and
//! a `QpSolver` kept on workspaces of the caller's (`fill`, `solve`,
//! `refine`, `solution`), both cold, so their ratio is the owned solver's
//! overhead.

use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_mpc::{ParametricQpSolver, QpSettings, ReferenceSolver};
use kestrel_qp::{ActiveSetSolver, Start, parametric::ParametricQp};
use kestrel_tricopter::{
    ProblemSize, default_weights, identified_model, tricopter_problem, tricopter_trim,
};
use nalgebra::DVector;
use std::hint::black_box;

fn solves(c: &mut Criterion) {
    let model = identified_model().expect("identified model");
    let trim = tricopter_trim(&model).expect("trim");
    let pinv = model.c.clone().pseudo_inverse(1e-12).expect("pinv");
    for (size, name) in [
        (ProblemSize::Thesis, "thesis N=2 n=4"),
        (ProblemSize::Larger, "larger N=10 n=16"),
    ] {
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, size, q1, q2).expect("problem");
        let mpqp = problem.to_mpqp();
        let mut solver = ReferenceSolver::new(&mpqp, QpSettings::default()).expect("solver");
        let settings = kestrel_qp::QpSettings::default();
        let mut owned = ActiveSetSolver::new(&mpqp, settings, Start::Cold).expect("owned solver");
        let qp = ParametricQp::from_mpqp(&mpqp).expect("parametric QP");
        let (ns, ni) = qp.workspace_len();
        let (mut scalars, mut indices) = (vec![0.0; ns], vec![0; ni]);
        let mut kept = qp
            .solver::<f64>(settings, &mut scalars, &mut indices)
            .expect("kept solver");
        let mut buf = qp.buffers::<f64>();
        let mut z = vec![0.0; qp.n()];
        for (label, rates) in [
            ("table 7.2 state", [0.2, 0.3, 0.4]),
            ("released at [2,2,2]", [2.0, 2.0, 2.0]),
        ] {
            let x = &pinv * DVector::from_column_slice(&rates);
            let theta = problem
                .theta(x.as_slice(), &[0.0, 0.0, 0.0, trim.hover_throttle])
                .expect("theta");
            let sol = solver.solve(&theta).expect("solves");
            eprintln!(
                "{name}, {label}: {} iterations, active bounds {}",
                sol.iterations,
                sol.lambda.iter().filter(|l| **l > 1e-6).count()
            );
            c.bench_function(&format!("clarabel QP solve, {name}, {label}"), |b| {
                b.iter(|| solver.solve(black_box(&theta)).expect("solves"))
            });
            c.bench_function(
                &format!("kestrel-qp ActiveSetSolver cold, {name}, {label}"),
                |b| {
                    b.iter(|| {
                        owned
                            .solve_into(black_box(theta.as_slice()), &mut z)
                            .expect("solves")
                    })
                },
            );
            c.bench_function(
                &format!("kestrel-qp kept QpSolver cold, {name}, {label}"),
                |b| {
                    b.iter(|| {
                        qp.fill(black_box(theta.as_slice()), &mut buf)
                            .expect("fill");
                        kept.solve(&buf.data(), Start::Cold).expect("solves");
                        kept.refine(&buf.data()).expect("refines");
                        kept.solution(&mut z).expect("solution")
                    })
                },
            );
        }
    }
}

criterion_group!(benches, solves);
criterion_main!(benches);
