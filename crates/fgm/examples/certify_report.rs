//! Release-mode report: the certificate against clarabel at many random
//! theta per problem (default 10^5), cold and warm start, f64, plus the
//! f32 / Q16 solvers against their stated bounds.
//!
//! `cargo run --release -p kestrel-fgm --example certify_report -- [samples] [problem.json ...]`
//! Without problem files it uses built-in condensed MPC problems.

#[path = "../tests/common/mod.rs"]
mod common;

use common::{Rng, mpc_problem, random_theta};
use kestrel_core::formats::MpqpProblem;
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::reference::ReferenceSolver;
use kestrel_fgm::{BoxQp, FgmDesign, FgmSettings, Preconditioner, Start, WarmStartAssumption};
use nalgebra::DVector;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let samples: usize = args.first().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let mut problems: Vec<(String, MpqpProblem)> = args
        .iter()
        .skip(1)
        .map(|p| {
            (
                p.clone(),
                MpqpProblem::read(std::path::Path::new(p)).expect("problem file"),
            )
        })
        .collect();
    if problems.is_empty() {
        problems.push(("random nx=5 nu=4 N=2".into(), mpc_problem(42, 5, 4, 2)));
        problems.push(("random nx=5 nu=4 N=4".into(), mpc_problem(43, 5, 4, 4)));
    }
    for (name, prob) in problems {
        report(&name, &prob, samples);
    }
}

fn report(name: &str, prob: &MpqpProblem, samples: usize) {
    let qp = BoxQp::from_mpqp(prob).expect("box problem");
    println!("== {name}: n = {}, p = {}", qp.n(), qp.p());
    let mut designs = Vec::new();
    for pc in [
        Preconditioner::None,
        Preconditioner::Jacobi,
        Preconditioner::OptimalDiagonal,
    ] {
        let d = FgmDesign::new(
            qp.clone(),
            FgmSettings {
                preconditioner: pc,
                ..Default::default()
            },
        )
        .expect("design");
        let c = d.certify(1e3).expect("certify");
        println!(
            "{:>17}: L = {:.4e}, mu = {:.4e}, cond = {:.4e}, Delta = {:.4e}, iterations(eps=1e3) = {}",
            pc.name(),
            d.spectrum.l,
            d.spectrum.mu,
            d.spectrum.condition(),
            d.delta(),
            c.iterations
        );
        designs.push(d);
    }
    let d = designs.pop().expect("optimal design");
    let mu_h = d.preconditioning.before.mu;
    // 1 us on every input (these problems have no designated first move).
    let eps_pwm = d
        .input_tolerance(1.0, kestrel_fgm::AppliedInputs::All)
        .expect("pwm tolerance")
        .eps;
    print!("eps table:");
    for e in [1e5, 1e4, 1e3, 1e2, eps_pwm] {
        print!(" {e:.3e} -> {}", d.certify(e).expect("cert").iterations);
    }
    println!("   (last: eps for 1 us, mu_H = {mu_h:.4e})");
    let mut reference = ReferenceSolver::new(&d.problem).expect("reference");
    let mut rng = Rng::new(2024);
    let t0 = Instant::now();
    let thetas: Vec<DVector<f64>> = (0..samples)
        .map(|_| random_theta(&mut rng, &d.problem.theta_lb, &d.problem.theta_ub))
        .collect();
    let best: Vec<f64> = thetas
        .iter()
        .map(|th| reference.solve(th).expect("clarabel").cost)
        .collect();
    println!(
        "clarabel references: {samples} solves in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    for eps in [1e3, eps_pwm] {
        let cert = d.certify(eps).expect("cert");
        let range = &d.problem.theta_ub - &d.problem.theta_lb;
        let assume = WarmStartAssumption {
            prev_eps: eps,
            theta_step: &range * 0.01,
        };
        let warm = d.certify_warm(eps, &assume).expect("warm");
        let data = d.data::<f64>(&cert, Some(warm.iterations)).expect("data");
        let f32d = d.data::<f32>(&cert, None).expect("f32");
        let q16d = d.data::<Q16>(&cert, None).expect("q16");
        let b32 = d.rounding_bound::<f32>(&cert);
        let bq = d.rounding_bound::<Q16>(&cert);
        let (mut wc, mut ww, mut v) = (f64::NEG_INFINITY, f64::NEG_INFINITY, 0usize);
        let (mut d32, mut dq, mut g32, mut gq) =
            (0.0f64, 0.0f64, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for (k, th) in thetas.iter().enumerate() {
            let z = DVector::from_vec(
                data.solve(th.as_slice(), Start::Cold, cert.iterations)
                    .expect("solve"),
            );
            let gap = d.problem.cost(&z, th) - best[k];
            wc = wc.max(gap);
            // Warm: previous solution at a theta one step away.
            let th0 = DVector::from_fn(th.len(), |i, _| {
                (th[i] + assume.theta_step[i] * rng.uniform(-1.0, 1.0))
                    .clamp(d.problem.theta_lb[i], d.problem.theta_ub[i])
            });
            let prev = data
                .solve(th0.as_slice(), Start::Cold, cert.iterations)
                .expect("solve");
            let zw = DVector::from_vec(
                data.solve(th.as_slice(), Start::Warm(&prev), warm.iterations)
                    .expect("solve"),
            );
            let gw = d.problem.cost(&zw, th) - best[k];
            ww = ww.max(gw);
            if gap > eps || gw > eps {
                v += 1;
            }
            let low = |out: Vec<f64>| DVector::from_vec(out);
            let t32: Vec<f32> = th.iter().map(|x| *x as f32).collect();
            let z32 = low(f32d
                .solve(&t32, Start::Cold, cert.iterations)
                .expect("f32")
                .iter()
                .map(|x| x.to_f64())
                .collect());
            let tq: Vec<Q16> = th.iter().map(|x| Q16::from_f64(*x)).collect();
            let zq = low(q16d
                .solve(&tq, Start::Cold, cert.iterations)
                .expect("q16")
                .iter()
                .map(|x| x.to_f64())
                .collect());
            d32 = d32.max((&z32 - &z).norm());
            dq = dq.max((&zq - &z).norm());
            g32 = g32.max(d.problem.cost(&z32, th) - best[k]);
            gq = gq.max(d.problem.cost(&zq, th) - best[k]);
        }
        println!(
            "eps = {eps:.4e}: cold {} it, worst J - J* = {wc:.4e}; warm {} it (refined: {}), worst = {ww:.4e}; violations: {v}/{samples}",
            cert.iterations, warm.iterations, warm.refined
        );
        if let (Some(b32), Some(bq)) = (b32, bq) {
            println!(
                "   f32: |z - z64| max {d32:.3e} (bound {:.3e}), J - J* max {g32:.3e} (bound {:.3e})",
                b32.distance_bound, b32.cost_bound
            );
            println!(
                "   Q16: |z - z64| max {dq:.3e} (bound {:.3e}), J - J* max {gq:.3e} (bound {:.3e})",
                bq.distance_bound, bq.cost_bound
            );
        }
    }
}
