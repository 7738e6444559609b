//! The explicit solution against independent computations: clarabel's QP
//! solution at 10^4 random parameters per problem (through the tree, in
//! f64), coverage of every sampled parameter, and region counts against a
//! brute-force enumeration of active sets, on regular and degenerate problems.

mod common;

use common::clarabel_qp;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::mpqp::Rng;
use kestrel_empc::{
    Outputs, Settings, TreeSettings, brute_force_active_sets, build_compact, build_controller,
    evaluate, solve, testing,
};
use nalgebra::{DMatrix, DVector};

fn sample(prob: &MpqpProblem, rng: &mut Rng) -> Vec<f64> {
    common::box_point(prob.theta_lb.as_slice(), prob.theta_ub.as_slice(), rng)
}

/// Solves, builds the tree and checks 10^4 random parameters against clarabel.
fn check_against_clarabel(name: &str, prob: &MpqpProblem, samples: usize) {
    let sol = solve(prob, &Settings::default()).unwrap();
    let ctl = build_controller(prob, &sol, &TreeSettings::default()).unwrap();
    assert_eq!(ctl.stats.ambiguous_leaves, 0, "{name}");
    let t = ctl.tables.tables();
    // The compact layout (one tree per output) must give the same answers.
    let compact = build_compact(prob, &sol, &TreeSettings::default()).unwrap();
    assert_eq!(compact.ambiguous_leaves, 0, "{name}");
    let tc = compact.tables.tables();
    let mut worst_compact = 0.0_f64;
    let mut rng = Rng::new(42);
    let mut worst = 0.0_f64;
    let mut infeasible = 0;
    for _ in 0..samples {
        let theta = sample(prob, &mut rng);
        let Some(zref) = clarabel_qp(prob, &theta) else {
            infeasible += 1;
            continue;
        };
        // Covered by a region of the solution.
        let r = sol.locate(&theta, 1e-9);
        assert!(r.is_some(), "{name}: theta {theta:?} is not covered");
        let mut z = vec![0.0; prob.n()];
        let e = dispatch(&t, &theta, &mut z);
        assert!(!e.outside, "{name}: theta {theta:?} flagged outside");
        let scale = 1.0 + zref.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        for j in 0..prob.n() {
            worst = worst.max((z[j] - zref[j]).abs() / scale);
        }
        let mut zc = vec![0.0; prob.n()];
        let ec = dispatch(&tc, &theta, &mut zc);
        assert!(
            !ec.outside,
            "{name}: theta {theta:?} flagged outside (compact)"
        );
        for j in 0..prob.n() {
            worst_compact = worst_compact.max((zc[j] - zref[j]).abs() / scale);
        }
    }
    eprintln!(
        "{name} compact: depth {}, {} nodes, {} bytes(f32), worst |z - z_clarabel| {worst_compact:.2e}",
        compact.depth,
        compact.tables.nodes.len(),
        compact.tables.bytes(4)
    );
    assert!(
        worst_compact <= 1e-8,
        "{name}: compact layout, worst deviation {worst_compact:e}"
    );
    eprintln!(
        "{name}: {} regions, {} laws, tree depth {} nodes {} bytes(f32) {}, worst |z - z_clarabel| {worst:.2e}, {infeasible} infeasible samples",
        sol.regions.len(),
        ctl.stats.distinct_laws,
        ctl.stats.depth,
        ctl.stats.nodes,
        ctl.tables.bytes(4)
    );
    assert!(worst <= 1e-8, "{name}: worst deviation {worst:e}");
}

/// `evaluate` needs the parameter count as a constant.
fn dispatch<T: kestrel_empc::TreeTables<f64>>(
    t: &T,
    theta: &[f64],
    z: &mut [f64],
) -> kestrel_empc::Evaluation {
    match theta.len() {
        2 => evaluate(t, &<[f64; 2]>::try_from(theta).unwrap(), z),
        3 => evaluate(t, &<[f64; 3]>::try_from(theta).unwrap(), z),
        4 => evaluate(t, &<[f64; 4]>::try_from(theta).unwrap(), z),
        9 => evaluate(t, &<[f64; 9]>::try_from(theta).unwrap(), z),
        _ => unreachable!(),
    }
    .unwrap()
}

fn small_blocked(seed: u64) -> MpqpProblem {
    let mut s = testing::random_system(2, 1, 0, 0.9, seed);
    s.horizon = 6;
    s.free_moves = 3;
    s.x_bound = 10.0;
    s.r = 0.01;
    s.condense()
}

/// Adds a constraint that is the sum of two others (LICQ fails where both are active).
fn with_implied_row(mut prob: MpqpProblem, i: usize, j: usize) -> MpqpProblem {
    let m = prob.m();
    let (n, p) = (prob.n(), prob.p());
    let g = DMatrix::from_fn(m + 1, n, |r, c| {
        if r < m {
            prob.g[(r, c)]
        } else {
            prob.g[(i, c)] + prob.g[(j, c)]
        }
    });
    let e = DMatrix::from_fn(m + 1, p, |r, c| {
        if r < m {
            prob.e[(r, c)]
        } else {
            prob.e[(i, c)] + prob.e[(j, c)]
        }
    });
    let w = DVector::from_fn(m + 1, |r, _| {
        if r < m {
            prob.w[r]
        } else {
            prob.w[i] + prob.w[j]
        }
    });
    prob.g = g;
    prob.e = e;
    prob.w = w;
    prob
}

/// Constraints through the origin: many active at theta = 0 at once, with
/// zero multipliers there (weakly active).
fn through_origin() -> MpqpProblem {
    MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1",
        "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
        "G": [[1, 0], [0, 1], [1, 1], [-1, 0], [0, -1], [1, 1]],
        "W": [0, 0, 0, 1, 1, 0], "E": [[0, 0], [0, 0], [0, 0], [0, 0], [0, 0], [0, 0]],
        "theta_lb": [-1, -1], "theta_ub": [1, 1]}"#,
    )
    .unwrap()
}

fn compare_brute_force(name: &str, prob: &MpqpProblem) -> usize {
    let sol = solve(prob, &Settings::default()).unwrap();
    let mut found: Vec<Vec<usize>> = sol.regions.iter().map(|r| r.active_set.clone()).collect();
    found.sort();
    let brute = brute_force_active_sets(prob, &Settings::default()).unwrap();
    assert_eq!(found, brute, "{name}: explorer vs brute force");
    found.len()
}

#[test]
fn region_counts_equal_brute_force() {
    for seed in 0..4 {
        let p = small_blocked(seed);
        let n = compare_brute_force(&format!("blocked seed {seed}"), &p);
        assert!(
            n > 3,
            "seed {seed}: only {n} regions, the test would be weak"
        );
    }
    compare_brute_force("thesis-sized", &testing::thesis_sized(1));
}

#[test]
fn degenerate_problems_equal_brute_force() {
    // Coincident rows (move blocking) are in every blocked problem; here also
    // a row implied by two others (LICQ violated) and rows through one point.
    let n = compare_brute_force("implied row", &with_implied_row(small_blocked(1), 0, 1));
    assert!(n > 3);
    let n = compare_brute_force("through origin", &through_origin());
    assert!(n >= 3);
    let sol = solve(&small_blocked(2), &Settings::default()).unwrap();
    assert!(sol.stats.duplicate_rows > 0);
}

#[test]
fn tree_matches_clarabel_small_and_degenerate() {
    check_against_clarabel("blocked seed 0", &small_blocked(0), 10_000);
    check_against_clarabel(
        "implied row",
        &with_implied_row(small_blocked(1), 0, 1),
        10_000,
    );
    check_against_clarabel("through origin", &through_origin(), 10_000);
}

#[test]
fn tree_matches_clarabel_thesis_sized() {
    check_against_clarabel("thesis-sized", &testing::thesis_sized(1), 10_000);
}

#[test]
fn first_move_tree_and_f32_tables() {
    let prob = small_blocked(3);
    let sol = solve(&prob, &Settings::default()).unwrap();
    let settings = TreeSettings {
        outputs: Outputs::First(1),
        ..Default::default()
    };
    let ctl = build_controller(&prob, &sol, &settings).unwrap();
    let full = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    assert!(ctl.stats.distinct_laws <= full.stats.distinct_laws);
    let t32 = ctl.tables.cast::<f32>();
    let mut rng = Rng::new(7);
    for _ in 0..2000 {
        let theta = sample(&prob, &mut rng);
        let r = sol.locate(&theta, 1e-9).unwrap();
        let want = sol.regions[r].z(&theta)[0];
        let mut z = [0.0f64];
        evaluate(&ctl.tables.tables(), &[theta[0], theta[1]], &mut z).unwrap();
        assert!((z[0] - want).abs() < 1e-9);
        let mut z32 = [0.0f32];
        let th32 = [theta[0] as f32, theta[1] as f32];
        evaluate(&t32.tables(), &th32, &mut z32).unwrap();
        assert!((z32[0] as f64 - want).abs() < 1e-4, "{} vs {want}", z32[0]);
    }
}
