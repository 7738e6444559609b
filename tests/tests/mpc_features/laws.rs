//! The laws: the explicit law (kestrel-empc) of small combinations, and
//! the MPC law (kestrel-mpc) in closed loop, against the references.

use super::cases::{Feature, Rng, plain, random_model, settings};
use super::common::{SAMPLES, rel_vec, seed_offset};
use super::exact::{Outcome, solve_exact};
use super::reference::Family;
use Feature::*;
use kestrel_empc::ExplicitSolver;
use kestrel_mpc::{MpcError, MpcProblem, ParametricQpSolver, QpSettings, ReferenceSolver};
use nalgebra::DVector;

#[test]
fn explicit_law_equals_both_references() {
    // (name, features, (nx, nu, ny), blocks): at most 6 decision variables.
    type Combo = (
        &'static str,
        Vec<Feature>,
        (usize, usize, usize),
        &'static [usize],
    );
    let combos: [Combo; 8] = [
        (
            "du weight + du bounds",
            vec![DuWeight, DuBounds],
            (2, 1, 1),
            &[1, 2, 2],
        ),
        (
            "soft output bounds",
            vec![OutputSoft],
            (2, 1, 1),
            &[1, 2, 2],
        ),
        (
            "hard output bounds + terminal set, LQ terminal",
            vec![OutputHard, TerminalSet, TerminalLq],
            (2, 1, 1),
            &[1, 2, 2],
        ),
        (
            "preview + input target parameter + parameter-dependent input bounds",
            vec![Preview, TargetParameter, ParamInputBounds, SmallTheta],
            (2, 1, 1),
            &[1, 2, 2],
        ),
        (
            "soft state bounds, no terminal cost",
            vec![StateSoft, TerminalNone],
            (2, 1, 1),
            &[1, 2, 2],
        ),
        (
            "hard state bounds, terminal state matrix, no blocking",
            vec![StateHard, TerminalState],
            (2, 1, 2),
            &[1, 1, 1, 1],
        ),
        (
            "du bounds + soft output bounds + fixed target, no blocking",
            vec![DuBounds, OutputSoft, TargetFixed],
            (3, 1, 1),
            &[1, 1, 1],
        ),
        (
            "two inputs: du weight + parameter-dependent input bounds",
            vec![DuWeight, ParamInputBounds, SmallTheta],
            (2, 2, 1),
            &[1, 2],
        ),
    ];
    let n = SAMPLES;
    let start = std::time::Instant::now();
    let mut worst = 0.0_f64;
    for (ci, (name, features, dims, blocks)) in combos.iter().enumerate() {
        let mut rng = Rng::new(500 + ci as u64 + seed_offset());
        let dims = *dims;
        let model = random_model(&mut rng, dims.0, dims.1, dims.2);
        let s = settings(&mut rng, dims, Some(blocks), features);
        let prob = MpcProblem::build(&model, &s).unwrap();
        assert!(prob.n() <= 6, "{name}: n = {}", prob.n());
        let mpqp = prob.to_mpqp();
        let t0 = std::time::Instant::now();
        let mut explicit = ExplicitSolver::build(&mpqp, &kestrel_empc::Settings::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let build_s = t0.elapsed().as_secs_f64();
        let mut qp = ReferenceSolver::new(&mpqp, QpSettings::default()).unwrap();
        let pl = plain(&model, &s);
        let (mut optimal, mut active, mut w) = (0, 0, 0.0_f64);
        let mut ze = vec![0.0; prob.n()];
        for _ in 0..n {
            let theta = rng.in_box(&prob.theta_lb, &prob.theta_ub);
            let qpr = pl.qp(&theta);
            let (sol, exact) = match (qp.solve(&theta), solve_exact(&qpr)) {
                (Ok(sol), Outcome::Optimal(e)) => (sol, e),
                (Err(MpcError::Infeasible), Outcome::Infeasible) => continue,
                (c, r) => panic!(
                    "{name}: verdicts differ at {theta}: {:?} vs {r:?}",
                    c.map(|s| s.z)
                ),
            };
            assert!(sol.polished);
            explicit.solve_into(theta.as_slice(), &mut ze).unwrap();
            let nu = dims.1;
            let d = rel_vec(&ze[..nu], &sol.z.as_slice()[..nu])
                .max(rel_vec(&ze[..nu], &pl.moves(&exact.v).as_slice()[..nu]))
                .max(rel_vec(&ze, sol.z.as_slice()));
            assert!(
                d <= 1e-8,
                "{name}: explicit {ze:?} vs condensed {} vs uncondensed {} at theta {theta}",
                sol.z,
                pl.moves(&exact.v)
            );
            w = w.max(d);
            optimal += 1;
            active += usize::from(
                (0..qpr.family.len())
                    .any(|i| exact.active[i] && qpr.family[i] != Family::SlackSign),
            );
        }
        eprintln!(
            "explicit law, {name} (n = {}, p = {}, m = {}): {} regions built in {build_s:.2} s; {optimal} of {n} parameters feasible, {active} with an active bound; worst relative difference {w:.1e}; {} outside",
            prob.n(),
            prob.p(),
            prob.m(),
            explicit.regions(),
            explicit.outside()
        );
        assert_eq!(explicit.outside(), 0, "{name}");
        assert!(
            optimal * 5 >= n && active * 10 >= optimal,
            "{name}: {optimal} feasible of {n}, {active} with an active bound"
        );
        worst = worst.max(w);
    }
    eprintln!(
        "explicit laws: worst relative difference {worst:.1e} in {:.1} s",
        start.elapsed().as_secs_f64()
    );
}

#[test]
fn mpc_law_applies_the_reference_first_move_in_closed_loop() {
    // The law assembles theta itself (its remembered previous input, the
    // references of the preview, the target and the parameters): its input
    // must be the reference's first move at the theta read the documented
    // way, step after step.
    let combos: [&[Feature]; 3] = [
        &[
            DuWeight,
            DuBounds,
            OutputSoft,
            Preview,
            TargetParameter,
            ParamInputBounds,
            TerminalLq,
        ],
        &[DuWeight, DuBounds, StateSoft, Preview, TargetFixed],
        &[
            Preview,
            ParamInputBounds,
            ParamOtherBounds,
            OutputSoft,
            TerminalNone,
        ],
    ];
    let mut rng = Rng::new(900 + seed_offset());
    let (mut steps, mut worst) = (0, 0.0_f64);
    for features in combos {
        for blocking in [None, Some(&[1usize, 2, 2][..])] {
            for _ in 0..3 {
                let dims = (rng.int(2, 4), rng.int(1, 3), rng.int(1, 3));
                let model = random_model(&mut rng, dims.0, dims.1, dims.2);
                let s = settings(&mut rng, dims, blocking, features);
                let prob = MpcProblem::build(&model, &s).unwrap();
                let pl = plain(&model, &s);
                let mut law = kestrel_mpc::MpcLaw::clarabel(&prob, QpSettings::default()).unwrap();
                let nu = dims.1;
                let params: Vec<f64> = s
                    .parameters
                    .iter()
                    .map(|p| rng.uniform(p.min, p.max))
                    .collect();
                let target = DVector::from_fn(nu, |_, _| 0.3 * rng.sym());
                let mut x = DVector::from_fn(dims.0, |_, _| rng.sym());
                let mut u_prev = DVector::zeros(nu);
                for k in 0..30 {
                    let refs: Vec<f64> = (0..s.preview * dims.2)
                        .map(|_| s.reference_bound * rng.sym())
                        .collect();
                    let mut r_law = refs.clone();
                    if matches!(s.input_target, kestrel_mpc::InputTarget::Parameter) {
                        r_law.extend(target.iter());
                    }
                    r_law.extend_from_slice(&params);
                    let mut u = vec![0.0; nu];
                    let got =
                        kestrel_core::ControlLaw::control(&mut law, x.as_slice(), &r_law, &mut u);
                    let theta = pl.assemble(&x, &u_prev, &refs, &target, &params);
                    match (got, solve_exact(&pl.qp(&theta))) {
                        (Ok(()), Outcome::Optimal(e)) => {
                            let want = e.v.rows(pl.ui(0), nu).into_owned();
                            let d = rel_vec(&u, want.as_slice());
                            assert!(
                                d <= 1e-8,
                                "{features:?} step {k}: law {u:?} vs reference {want}"
                            );
                            worst = worst.max(d);
                            if pl.has_prev() {
                                assert_eq!(law.previous_input(), &u[..], "remembered input");
                            }
                            u_prev = DVector::from_column_slice(&u);
                        }
                        (got, r) => panic!("{features:?} step {k}: law {got:?}, reference {r:?}"),
                    }
                    x = &pl.a * &x
                        + &pl.b * &u_prev
                        + DVector::from_fn(dims.0, |_, _| 0.05 * rng.sym());
                    steps += 1;
                }
            }
        }
    }
    eprintln!(
        "MPC law in closed loop: {steps} steps, worst relative difference from the reference {worst:.1e}"
    );
}
