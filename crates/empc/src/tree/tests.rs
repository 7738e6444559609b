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

#[test]
fn intern_keeps_multiples_of_a_row_apart() {
    use crate::tree::assemble::intern;
    use std::collections::HashMap;
    let (mut rows, mut index) = (Vec::new(), HashMap::new());
    let mut add = |r: &[f64]| intern(&mut rows, &mut index, r, 1e-9);
    // Constant rows above 1 (input bounds): multiples, not the same row.
    let a = add(&[0.0, 1.1903455374414478]);
    assert_ne!(a, add(&[0.0, 1.001737213000038]));
    assert_ne!(add(&[2.0, 0.0]), add(&[3.0, 0.0]));
    assert_ne!(add(&[0.5, 0.0]), add(&[0.25, 0.0]));
    // Rounding noise: the same row.
    assert_eq!(a, add(&[3e-16, 1.1903455374414473]));
}

/// Three intervals of one parameter, the outer two with one law (z = 0),
/// the middle one z = theta: no facet leaves fewer laws on both sides, the
/// tree must still separate them (it splits the cell).
#[test]
fn separates_regions_of_one_law_around_another() {
    use crate::mpqp::CriticalRegion;
    use nalgebra::{DMatrix, DVector};
    let prob = MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1", "H": [[1]], "F": [[1]], "G": [[0]], "W": [1],
            "E": [[0]], "theta_lb": [-3], "theta_ub": [3]}"#,
    )
    .unwrap();
    let region = |lo: f64, hi: f64, gain: f64| CriticalRegion {
        active_set: Vec::new(),
        a: DMatrix::from_row_slice(2, 1, &[1.0, -1.0]),
        b: DVector::from_vec(vec![hi, -lo]),
        fz: DMatrix::from_element(1, 1, gain),
        gz: DVector::zeros(1),
        center: DVector::from_element(1, 0.5 * (lo + hi)),
        radius: 0.5 * (hi - lo),
    };
    let sol = MpqpSolution {
        n: 1,
        p: 1,
        regions: vec![
            region(-3.0, -1.0, 0.0),
            region(-1.0, 1.0, 1.0),
            region(1.0, 3.0, 0.0),
        ],
        hull_a: DMatrix::zeros(0, 1),
        hull_b: DVector::zeros(0),
        theta_lb: DVector::from_element(1, -3.0),
        theta_ub: DVector::from_element(1, 3.0),
        stats: Default::default(),
    };
    for method in [TreeMethod::Lp, TreeMethod::Sampled] {
        let settings = TreeSettings {
            method,
            ..TreeSettings::default()
        };
        let ctl = build_controller(&prob, &sol, &settings).unwrap();
        assert_eq!(ctl.stats.distinct_laws, 2);
        assert_eq!(ctl.stats.ambiguous_leaves, 0, "{method:?}");
        assert_eq!(mismatches(&sol, &ctl.tables, 500, 3), 0, "{method:?}");
    }
}
