//! Fast gradient solves on kestrel-mpc's tricopter problems built from the
//! identified 5-state model (`models/tricopter-blackbox-5.json`):
//! thesis-sized (N = 2, one block, n = 4) and larger (N = 10, blocks
//! [1, 1, 2, 6], n = 16), each certified for the eps that keeps every
//! applied PWM pulse within 1 us of the optimum, in f64, f32 and Q16,
//! against the clarabel reference solve of the same QP at the same theta
//! (kestrel-mpc's `ReferenceSolver`, the one of the `mpc` bench, and
//! kestrel-fgm's own box-QP reference). Two parameters as in the `mpc`
//! bench: the state of Table 7.2 (rates [0.2, 0.3, 0.4] rad/s) and the
//! release at [2, 2, 2] rad/s, reference 0, hover throttle.
//!
//! The speed-up is the ratio within one group (measured back to back, so
//! a shared, loaded machine slows both alike).
//!
//! `cargo bench -p kestrel-benches --bench fgm -- --warm-up-time 1 --measurement-time 3`

use criterion::measurement::Measurement;
use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_core::formats::SsModel;
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::reference::ReferenceSolver;
use kestrel_fgm::{
    AppliedInputs, BoxQp, FgmDesign, FgmSettings, FgmTables, FgmWorkspace, Momentum,
};
use kestrel_mpc::QpSettings;
use kestrel_tricopter::{ProblemSize, default_weights, tricopter_problem, tricopter_trim};
use nalgebra::DVector;
use std::hint::black_box;

/// Parameters: 5 states, 3 references, the throttle.
const P: usize = 9;

fn model() -> SsModel {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../models/tricopter-blackbox-5.json"
    );
    // KESTREL_FGM_MODEL overrides the fixture (e.g. a committed version
    // while the shared file is being re-identified).
    let path = std::env::var("KESTREL_FGM_MODEL").unwrap_or_else(|_| path.to_string());
    SsModel::read(std::path::Path::new(&path)).expect("identified model")
}

fn bench_size<M: Measurement, const N: usize>(
    c: &mut Criterion<M>,
    group: &str,
    name: &str,
    size: ProblemSize,
) {
    let model = model();
    let (q1, q2) = default_weights();
    let prob = tricopter_problem(&model, size, q1, q2).expect("problem");
    assert_eq!(prob.p(), P, "parameter count");
    let mpqp = prob.to_mpqp();
    let qp = BoxQp::from_mpqp(&mpqp).expect("box");
    let d = FgmDesign::new(
        qp,
        FgmSettings {
            momentum: Momentum::Constant,
            ..FgmSettings::default()
        },
    )
    .expect("design");
    let pwm = d
        .input_tolerance(1.0, AppliedInputs::FirstMove(4))
        .expect("pwm eps");
    let cert = d.certify(pwm.eps).expect("certify");
    eprintln!(
        "{name}: n = {N}, eps = {:.3e} (1 us on the first move), certified iterations = {}",
        pwm.eps, cert.iterations
    );
    let t64: FgmTables<f64, N, P, 1> = d.tables(&cert, None).expect("f64");
    let t32: FgmTables<f32, N, P, 1> = d.tables(&cert, None).expect("f32");
    let tq: FgmTables<Q16, N, P, 1> = d.tables(&cert, None).expect("q16");
    let trim = tricopter_trim(&model).expect("trim");
    let pinv = model.c.clone().pseudo_inverse(1e-12).expect("pinv");
    let mut mpc_ref =
        kestrel_mpc::ReferenceSolver::new(&mpqp, QpSettings::default()).expect("clarabel");
    let mut fgm_ref = ReferenceSolver::new(&d.problem).expect("reference");
    for (label, rates) in [
        ("table 7.2 state", [0.2, 0.3, 0.4]),
        ("released at [2,2,2]", [2.0; 3]),
    ] {
        let x = &pinv * DVector::from_column_slice(&rates);
        let th = prob
            .theta(x.as_slice(), &[0.0, 0.0, 0.0, trim.hover_throttle])
            .expect("theta");
        let th64: [f64; P] = core::array::from_fn(|i| th[i]);
        let th32: [f32; P] = core::array::from_fn(|i| th[i] as f32);
        let thq: [Q16; P] = core::array::from_fn(|i| Q16::from_f64(th[i]));
        // The FGM answer is within 1 us of clarabel's here too.
        let mut w = FgmWorkspace::<f64, N>::new();
        let z = t64.solve(&th64, &mut w).expect("solve");
        let best = mpc_ref.solve(&th).expect("clarabel");
        let err = z
            .iter()
            .zip(best.z.iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!("{name}, {label}: max |z_fgm - z_clarabel| = {err:.3e} us");
        let mut g = c.benchmark_group(format!("{group}/{name}/{label}"));
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
        g.bench_function("clarabel_mpc", |b| {
            b.iter(|| mpc_ref.solve(black_box(&th)).expect("clarabel"))
        });
        g.bench_function("clarabel_box", |b| {
            b.iter(|| fgm_ref.solve(black_box(&th)).expect("clarabel"))
        });
        g.finish();
    }
}

fn fgm(c: &mut Criterion) {
    bench_size::<_, 4>(c, "fgm", "thesis", ProblemSize::Thesis);
    bench_size::<_, 16>(c, "fgm", "larger", ProblemSize::Larger);
}

criterion_group!(benches, fgm);
criterion_main!(benches);
