//! Regressions found by the kestrel-mpc feature cross-check
//! (tests/tests/mpc_features.rs in the workspace): problems where the tree
//! or the solver once went wrong, with the answers checked against the
//! region laws and clarabel.

mod common;

use common::clarabel_qp;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::mpqp::Rng;
use kestrel_empc::{Settings, TreeSettings, build_controller, evaluate_with, solve};

fn load(name: &str) -> MpqpProblem {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    MpqpProblem::from_json_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A du-weight + du-bounds MPC (n = 3, p = 4) whose tree over all of `z`
/// once had two ambiguous leaves: the first move was right everywhere, the
/// later moves wrong at about 1 % of the parameters.
#[test]
fn tree_over_all_outputs_has_no_ambiguous_leaf() {
    let prob = load("ambiguous-leaves.mpqp.json");
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    assert_eq!(ctl.stats.ambiguous_leaves, 0);
    let t = ctl.tables.tables();
    let mut scratch = [0.0; 4];
    let mut z = [0.0; 3];
    // The two parameters of the report, with the QP's z.
    let cases = [
        (
            [
                1.8467310723415378,
                -1.7747835206641156,
                1.0208319136018806,
                -0.31560568392244503,
            ],
            [1.1903455374414478, 1.1903455374414478, 1.001737213000039],
        ),
        (
            [
                1.1238755738293418,
                -0.03319306233910746,
                1.1215593387589982,
                0.7310282249363234,
            ],
            [1.1903455374414478, 1.001737213000039, 0.8131288885586303],
        ),
    ];
    for (theta, want) in cases {
        evaluate_with(&t, &theta, &mut scratch, &mut z).unwrap();
        for (a, b) in z.iter().zip(want) {
            assert!(
                (a - b).abs() < 1e-8,
                "theta {theta:?}: tree {z:?}, QP {want:?}"
            );
        }
    }
    // And at random parameters: the tree equals the law of a region
    // containing theta.
    let mut rng = Rng::new(7);
    let (lb, ub) = (prob.theta_lb.as_slice(), prob.theta_ub.as_slice());
    let mut checked = 0;
    for _ in 0..20_000 {
        let theta = common::box_point(lb, ub, &mut rng);
        let Some(r) = sol.regions.iter().find(|r| r.contains(&theta, -1e-9)) else {
            continue;
        };
        evaluate_with(&t, &theta, &mut scratch, &mut z).unwrap();
        let want = r.z(&theta);
        for (a, b) in z.iter().zip(want.iter()) {
            assert!(
                (a - b).abs() < 1e-8,
                "theta {theta:?}: tree {z:?}, region {want:?}"
            );
        }
        checked += 1;
    }
    assert!(checked > 10_000, "{checked}");
}

/// Soft-state problems (3 moves + 2 slacks) where `solve` once stopped
/// with "the QP at theta = [...] did not converge" although the QP there
/// is well posed: the solution must cover the reported parameter with
/// clarabel's answer.
#[test]
fn soft_state_problems_solve() {
    for (name, theta) in [
        (
            "noconverge-seed4.mpqp.json",
            [1.0293764879910174, -1.6446482069859927, 0.9603996059997282],
        ),
        (
            "noconverge-seed6.mpqp.json",
            [0.017991729101878434, 0.335571113694912, 0.9999961983804386],
        ),
    ] {
        let prob = load(name);
        let sol = solve(&prob, &Settings::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let want = clarabel_qp(&prob, &theta).unwrap();
        let r = sol
            .regions
            .iter()
            .find(|r| r.contains(&theta, 1e-9))
            .unwrap_or_else(|| panic!("{name}: no region contains theta"));
        let z = r.z(&theta);
        for (a, b) in z.iter().zip(&want) {
            assert!(
                (a - b).abs() < 1e-6,
                "{name}: region {z:?}, clarabel {want:?}"
            );
        }
    }
}

/// The explicit MPC over all of `z` equals the region laws: the problem of
/// the ambiguous leaves through [`ExplicitSolver`], and a du-bounds + soft
/// output MPC (n = 4, p = 5, 480 regions) whose tree (about 34,000 nodes)
/// exceeds the `u16` layout, so the solver takes the `u32` tables.
#[test]
fn explicit_solver_is_exact_and_takes_wide_tables() {
    use kestrel_empc::{AnyTables, ExplicitSolver};
    use kestrel_mpc::ParametricQpSolver;
    for (name, wide) in [
        ("ambiguous-leaves.mpqp.json", false),
        ("wide-tree.mpqp.json", true),
    ] {
        let prob = load(name);
        let sol = solve(&prob, &Settings::default()).unwrap();
        let mut s = ExplicitSolver::build(&prob, &Settings::default()).unwrap();
        assert_eq!(matches!(s.tables(), AnyTables::Wide(_)), wide, "{name}");
        let mut rng = Rng::new(3);
        let (lb, ub) = (prob.theta_lb.as_slice(), prob.theta_ub.as_slice());
        let mut z = vec![0.0; prob.n()];
        let mut checked = 0;
        for _ in 0..2000 {
            let theta = common::box_point(lb, ub, &mut rng);
            let Some(want) = sol.first_outputs_at(&theta, prob.n()) else {
                continue;
            };
            s.solve_into(&theta, &mut z).unwrap();
            for (a, b) in z.iter().zip(&want) {
                assert!(
                    (a - b).abs() < 1e-8 * (1.0 + b.abs()),
                    "{name} at {theta:?}: {z:?}, region {want:?}"
                );
            }
            checked += 1;
        }
        assert!(checked > 500, "{name}: {checked}");
    }
}

/// The double integrator of `examples/double-integrator.json` (`kestrel
/// c2d --ts 0.1`) with `kestrel mpc --horizon 12 --u-min -1 --u-max 1
/// --state-min -5,-2 --state-max 5,2` (n = 12, m = 72, p = 3): `solve`
/// once stopped with "the QP at theta = [...] did not converge". At that
/// degenerate vertex a state row that depends on the working rows was
/// also active, and its rounding (`g_i p` of 1e-13 on a zero slack) won
/// the ratio test: the working rows became singular. The solution must
/// hold the reported parameter, and at random parameters agree with two
/// other solvers: kestrel-qp's dual active set (feasible or not, and `z`)
/// everywhere, and clarabel wherever it converges at its tight tolerances
/// (about half of these parameters; it stalls at the others, the reported
/// one among them).
#[test]
fn degenerate_state_bounds_solve() {
    let prob = load("noconverge-di12.mpqp.json");
    let sol = solve(&prob, &Settings::default()).unwrap();
    let reported = [1.0453093290100524, -1.5000110000000006, -1.0426529419463544];
    let mut rng = Rng::new(11);
    // The state bounds' box (the file's box is mostly infeasible: |x2| <= 10).
    let (lb, ub) = ([-5.0, -2.0, -3.0], [5.0, 2.0, 3.0]);
    let (mut feasible, mut infeasible, mut clarabel_checked) = (0, 0, 0);
    for k in 0..3000 {
        let theta = if k == 0 {
            reported.to_vec()
        } else {
            common::box_point(&lb, &ub, &mut rng)
        };
        let region = sol.regions.iter().find(|r| r.contains(&theta, 1e-9));
        let Some(want) = common::active_set_qp(&prob, &theta) else {
            assert!(k > 0, "the reported parameter is feasible");
            assert!(
                sol.regions.iter().all(|r| !r.contains(&theta, -1e-6)),
                "infeasible theta {theta:?} inside a region"
            );
            infeasible += 1;
            continue;
        };
        let r = region.unwrap_or_else(|| panic!("no region contains {theta:?}"));
        let z: Vec<f64> = r.z(&theta).iter().copied().collect();
        assert!(
            common::rel(&z, &want) < 1e-7,
            "theta {theta:?}: region {z:?}, kestrel-qp {want:?}"
        );
        if let Ok(Some(x)) = common::clarabel_qp_checked(&prob, &theta) {
            assert!(
                common::law_at_least_as_good(&prob, &theta, &z, &x) || common::rel(&z, &x) < 1e-7,
                "theta {theta:?}: region {z:?}, clarabel {x:?}"
            );
            clarabel_checked += 1;
        }
        feasible += 1;
    }
    assert!(
        feasible > 2000 && infeasible > 100 && clarabel_checked > 1000,
        "{feasible} {infeasible} {clarabel_checked}"
    );
}
