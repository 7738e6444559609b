//! The trees of both methods against the solution's own answers.

use crate::error::EmpcError;
use crate::mpqp::{MpqpSolution, Settings, solve};
use crate::rng::Rng;
use crate::testing;
use crate::tree::{Outputs, OwnedTables, TreeMethod, TreeSettings, build_controller};
use kestrel_core::formats::MpqpProblem;

/// Mismatches (beyond 1e-9 relative) of the tree against the region
/// lookup at `n` random parameters of the box; panics on an uncovered one.
fn mismatches(sol: &MpqpSolution, t: &OwnedTables<f64>, n: usize, seed: u64) -> usize {
    let mut rng = Rng::new(seed);
    let (p, k) = (t.n_params, t.n_outputs);
    let (mut z, mut scratch) = (vec![0.0; k], vec![0.0; p]);
    let mut bad = 0;
    for _ in 0..n {
        let th: Vec<f64> = (0..p)
            .map(|j| {
                let u = 0.5 * (rng.sym() + 1.0);
                sol.theta_lb[j] + u * (sol.theta_ub[j] - sol.theta_lb[j])
            })
            .collect();
        let want = sol
            .first_outputs_at(&th, k)
            .expect("every parameter of the box is covered");
        let e = crate::eval::evaluate_with(&t.tables(), &th, &mut scratch, &mut z).unwrap();
        assert!(!e.outside);
        if want
            .iter()
            .zip(&z)
            .any(|(a, b)| (a - b).abs() > 1e-9 * (1.0 + a.abs()))
        {
            bad += 1;
        }
    }
    bad
}

fn problems() -> Vec<(&'static str, MpqpProblem)> {
    let mut blocked = testing::random_system(2, 2, 1, 0.9, 7);
    blocked.horizon = 3;
    blocked.free_moves = 2;
    vec![
        ("thesis-sized", testing::thesis_sized(1)),
        (
            "random 3x2",
            testing::random_system(3, 2, 2, 0.95, 3).condense(),
        ),
        ("blocked 2x2", blocked.condense()),
    ]
}

#[test]
fn sampled_and_lp_trees_are_exact() {
    for (name, prob) in problems() {
        let sol = solve(&prob, &Settings::default()).unwrap();
        for k in [2, prob.n()] {
            let mut sizes = Vec::new();
            for method in [TreeMethod::Lp, TreeMethod::Sampled] {
                for clipping in [true, false] {
                    let settings = TreeSettings {
                        outputs: Outputs::First(k),
                        method,
                        clipping,
                        ..TreeSettings::default()
                    };
                    let ctl = build_controller(&prob, &sol, &settings).unwrap();
                    assert_eq!(ctl.stats.ambiguous_leaves, 0, "{name} {method:?}");
                    let bad = mismatches(&sol, &ctl.tables, 2000, 11);
                    assert_eq!(bad, 0, "{name}, k = {k}, {method:?}, clipping {clipping}");
                    sizes.push(ctl.stats.nodes);
                }
            }
            // Both methods build a tree (of comparable size).
            assert!(sizes.iter().all(|&s| s > 0), "{name}: {sizes:?}");
        }
    }
}

#[test]
fn sampled_tree_is_deterministic_and_parallel_invariant() {
    let prob = testing::thesis_sized(2);
    let sol = solve(&prob, &Settings::default()).unwrap();
    let build = |parallel| {
        let settings = TreeSettings {
            outputs: Outputs::First(4),
            method: TreeMethod::Sampled,
            parallel,
            ..TreeSettings::default()
        };
        build_controller(&prob, &sol, &settings).unwrap().tables
    };
    let a = build(true);
    assert_eq!(a, build(true));
    assert_eq!(a, build(false));
}

#[test]
fn node_cap_gives_too_large() {
    let prob = testing::thesis_sized(1);
    let sol = solve(&prob, &Settings::default()).unwrap();
    let settings = TreeSettings {
        outputs: Outputs::First(4),
        method: TreeMethod::Sampled,
        max_nodes: 20,
        ..TreeSettings::default()
    };
    let e = build_controller(&prob, &sol, &settings).unwrap_err();
    assert!(matches!(e, EmpcError::TooLarge(_)), "{e}");
    assert!(e.to_string().contains("max_nodes"), "{e}");
}
