//! Fast gradient solves per theta on kestrel-mpc's tricopter problems
//! (thesis-sized: n = 4; larger: n = 16), certified for the eps that keeps
//! every input within 1 us, in f64, f32 and Q16, against the clarabel
//! reference solve of the same QP.
//!
//! `cargo bench -p kestrel-benches --bench fgm -- --warm-up-time 1 --measurement-time 3`

use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::reference::ReferenceSolver;
use kestrel_fgm::{BoxQp, FgmDesign, FgmSettings, FgmTables, FgmWorkspace, Momentum};
use kestrel_mpc::{ProblemSize, default_weights, design_model, tricopter_problem};
use nalgebra::DVector;
use std::hint::black_box;

const P: usize = 12;

fn design(size: ProblemSize) -> FgmDesign {
    let model = design_model().expect("model");
    let (q1, q2) = default_weights();
    let prob = tricopter_problem(&model, size, q1, q2).expect("problem");
    assert_eq!(prob.p(), P, "parameter count");
    let qp = BoxQp::from_mpqp(&prob.to_mpqp()).expect("box");
    FgmDesign::new(
        qp,
        FgmSettings {
            momentum: Momentum::Constant,
            ..FgmSettings::default()
        },
    )
    .expect("design")
}

fn bench_size<const N: usize>(c: &mut Criterion, name: &str, size: ProblemSize) {
    let d = design(size);
    let eps = kestrel_fgm::eps_for_input_error(d.preconditioning.before.mu, 1.0);
    let cert = d.certify(eps).expect("certify");
    eprintln!(
        "{name}: n = {N}, eps = {eps:.3e}, certified iterations = {}",
        cert.iterations
    );
    let t64: FgmTables<f64, N, P, 1> = d.tables(&cert, None).expect("f64");
    let t32: FgmTables<f32, N, P, 1> = d.tables(&cert, None).expect("f32");
    let tq: FgmTables<Q16, N, P, 1> = d.tables(&cert, None).expect("q16");
    let mid = (&d.problem.theta_lb + &d.problem.theta_ub) * 0.5;
    let span = &d.problem.theta_ub - &d.problem.theta_lb;
    let th = DVector::from_fn(P, |i, _| {
        mid[i] + 0.3 * span[i] * if i % 2 == 0 { 1.0 } else { -1.0 }
    });
    let th64: [f64; P] = core::array::from_fn(|i| th[i]);
    let th32: [f32; P] = core::array::from_fn(|i| th[i] as f32);
    let thq: [Q16; P] = core::array::from_fn(|i| Q16::from_f64(th[i]));
    let mut g = c.benchmark_group(format!("fgm/{name}"));
    let mut w64 = FgmWorkspace::<f64, N>::new();
    g.bench_function("fgm_f64", |b| {
        b.iter(|| t64.solve(black_box(&th64), &mut w64).expect("solve"))
    });
    let mut w32 = FgmWorkspace::<f32, N>::new();
    g.bench_function("fgm_f32", |b| {
        b.iter(|| t32.solve(black_box(&th32), &mut w32).expect("solve"))
    });
    let mut wq = FgmWorkspace::<Q16, N>::new();
    g.bench_function("fgm_q16", |b| {
        b.iter(|| tq.solve(black_box(&thq), &mut wq).expect("solve"))
    });
    let reference = ReferenceSolver::new(&d.problem);
    g.bench_function("clarabel", |b| {
        b.iter(|| {
            reference
                .solve(&d.problem, black_box(&th))
                .expect("clarabel")
        })
    });
    g.finish();
}

fn fgm(c: &mut Criterion) {
    bench_size::<4>(c, "thesis", ProblemSize::Thesis);
    bench_size::<16>(c, "larger", ProblemSize::Larger);
}

criterion_group!(benches, fgm);
criterion_main!(benches);
