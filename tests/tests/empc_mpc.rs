//! kestrel-empc on kestrel-mpc's tricopter problem of the thesis's size
//! (N = 2, N_s = 1, 4 inputs; kestrel-mpc's design model is the 8-state
//! rates-plus-actuators linearisation, so theta = 8 states + 3 rate
//! references + throttle = 12 parameters). Every sampled parameter must be
//! covered and the region's law must equal kestrel-mpc's clarabel reference
//! solution. KNOWN DEFECT: on this badly scaled problem (throttle in us next
//! to rates in rad/s) the search tree misroutes about 1 parameter in 1000
//! to a neighbouring law; the test measures that rate and bounds it so a
//! regression shows, until the tree construction is fixed.

use kestrel_empc::mpqp::Rng;
use kestrel_empc::{Outputs, Settings, TreeSettings, build_controller, evaluate_with, solve};
use kestrel_mpc::{
    ProblemSize, QpSettings, ReferenceSolver, default_weights, design_model, tricopter_problem,
};
use nalgebra::DVector;

#[test]
fn thesis_sized_tricopter_explicit_law_matches_reference() {
    let model = design_model().unwrap();
    let (q1, q2) = default_weights();
    let mpc = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
    let prob = mpc.to_mpqp();
    if let Ok(p) = std::env::var("EMPC_DUMP") {
        std::fs::write(p, prob.to_json_string()).unwrap();
    }
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(
        &prob,
        &sol,
        &TreeSettings {
            outputs: Outputs::First(4),
            ..TreeSettings::default()
        },
    )
    .unwrap();
    eprintln!(
        "tricopter thesis-sized (p = {}, n = {}): {} regions, {} distinct laws, solve {:.4} s, tree depth {}, {} nodes, {} bytes (f32)",
        prob.p(),
        prob.n(),
        sol.regions.len(),
        ctl.stats.distinct_laws,
        sol.stats.solve_seconds,
        ctl.stats.depth,
        ctl.stats.nodes,
        ctl.tables.bytes(4)
    );
    assert_eq!(ctl.stats.ambiguous_leaves, 0);
    let mut reference = ReferenceSolver::new(&prob, QpSettings::default()).unwrap();
    let t = ctl.tables.tables();
    let p = prob.p();
    let mut rng = Rng::new(11);
    let mut scratch = vec![0.0; p];
    let mut z = vec![0.0; 4];
    let mut worst = 0.0_f64;
    let mut worst_region = 0.0_f64;
    let mut worst_tree = 0.0_f64;
    let mut misrouted = 0usize;
    for _ in 0..1000 {
        let theta: Vec<f64> = (0..p)
            .map(|j| {
                let (lo, hi) = (prob.theta_lb[j], prob.theta_ub[j]);
                lo + (hi - lo) * 0.5 * (rng.sym() + 1.0)
            })
            .collect();
        let ri = sol.locate(&theta, 1e-7);
        assert!(ri.is_some(), "theta {theta:?} not covered");
        let zr = sol.regions[ri.unwrap()].z(&theta);
        let r = reference
            .solve(&DVector::from_column_slice(&theta))
            .unwrap();
        let e = evaluate_with(&t, &theta, &mut scratch, &mut z).unwrap();
        assert!(!e.outside);
        let scale = 1.0 + r.z.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        for j in 0..4 {
            worst = worst.max((z[j] - r.z[j]).abs() / scale);
            worst_region = worst_region.max((zr[j] - r.z[j]).abs() / scale);
            worst_tree = worst_tree.max((zr[j] - z[j]).abs() / scale);
        }
        if (0..4).any(|j| (zr[j] - z[j]).abs() > 1e-6 * scale) {
            misrouted += 1;
        }
    }
    eprintln!(
        "worst relative deviation from the reference QP solution: tree {worst:.2e}, region law {worst_region:.2e}; tree vs region law {worst_tree:.2e}"
    );
    // The reference is an interior-point solution with default tolerances.
    assert!(
        worst_region < 1e-5,
        "region law vs reference: {worst_region:e}"
    );
    eprintln!("tree misrouted {misrouted} of 1000 parameters");
    assert!(misrouted <= 5, "tree misrouted {misrouted} of 1000");
}
