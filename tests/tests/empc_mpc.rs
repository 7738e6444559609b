//! kestrel-empc on kestrel-mpc's tricopter problems: the explicit law
//! through the search tree against kestrel-mpc's clarabel reference
//! solution at 10^4 random parameters per problem, with zero tolerated
//! mismatches, every parameter covered by a region, and the tree's answer
//! equal to the containing region's law.
//!
//! On these badly scaled problems (pulses in us, up to 2000) clarabel's
//! interior-point answer is accurate to about 1e-7 relative, so the tree is
//! compared with it at 1e-6, and to 1e-8 with an exact independent
//! reference: the KKT conditions solved for every linearly independent set
//! of at most `n` constraints (brute force, no exploration, no tree), the
//! set with the smallest KKT violation giving the optimum.
//!
//! - The thesis-sized problem of the issue: the identified 5-state
//!   black-box model `models/tricopter-blackbox-5.json`, `N = 2`, one block
//!   (`N_s = 1`), 4 inputs with the tricopter PWM bounds around `u0`:
//!   theta = 5 states + 3 rate references + throttle = 9 parameters,
//!   4 variables. Its f32 table sizes are printed, in the default layout
//!   and in the compact one (one tree per output), which is checked as
//!   exactly as the default one (the 8 kB target is reported, not asserted:
//!   the fixture may be re-identified).
//! - kestrel-mpc's 8-state rates-plus-actuators design model (12
//!   parameters), badly scaled (throttle in us next to rates in rad/s):
//!   it used to expose a tree misrouting of about 1 parameter in 1000
//!   (an LP returning a wrong optimum), now required to be exact.

use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_empc::mpqp::Rng;
use kestrel_empc::{
    Outputs, Settings, TreeSettings, build_compact, build_controller, evaluate_with, solve,
};
use kestrel_mpc::{QpSettings, ReferenceSolver};
use kestrel_tricopter::{ProblemSize, default_weights, design_model, tricopter_problem};
use nalgebra::{DMatrix, DVector};

/// The QP optimum at `theta` by enumerating active sets (exact KKT solves).
fn brute_force_kkt(prob: &MpqpProblem, theta: &DVector<f64>) -> DVector<f64> {
    let (n, m) = (prob.n(), prob.m());
    let rhs = prob.rhs(theta);
    let q = prob.linear_term(theta);
    let rscale = 1.0 + rhs.amax();
    let mut best: Option<(f64, DVector<f64>)> = None;
    for mask in 0u32..(1 << m) {
        let act: Vec<usize> = (0..m).filter(|&i| mask >> i & 1 == 1).collect();
        let k = act.len();
        if k > n {
            continue;
        }
        let mut kkt = DMatrix::zeros(n + k, n + k);
        kkt.view_mut((0, 0), (n, n)).copy_from(&prob.h);
        let mut b = DVector::zeros(n + k);
        b.rows_mut(0, n).copy_from(&(-&q));
        for (r, &i) in act.iter().enumerate() {
            for j in 0..n {
                kkt[(n + r, j)] = prob.g[(i, j)];
                kkt[(j, n + r)] = prob.g[(i, j)];
            }
            b[n + r] = rhs[i];
        }
        let Some(sol) = kkt.lu().solve(&b) else {
            continue; // dependent rows
        };
        let z = sol.rows(0, n).into_owned();
        let lam = sol.rows(n, k);
        let lscale = 1.0 + lam.amax();
        let primal = (&prob.g * &z - &rhs).max() / rscale;
        let dual = -lam.min() / lscale;
        let viol = primal.max(dual).max(0.0);
        if best.as_ref().is_none_or(|(v, _)| viol < *v) {
            best = Some((viol, z));
        }
    }
    let (viol, z) = best.unwrap();
    assert!(
        viol <= 1e-9,
        "no active set satisfies the KKT conditions: {viol:e}"
    );
    z
}

fn blackbox_model() -> SsModel {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../models/tricopter-blackbox-5.json"
    );
    SsModel::read(std::path::Path::new(path)).unwrap()
}

struct Report {
    regions: usize,
    laws: usize,
    bytes_f32: usize,
    compact_bytes_f32: usize,
}

/// Solves, builds the first-move tree and checks `samples` random parameters.
fn check(name: &str, prob: &MpqpProblem, samples: usize) -> Report {
    if let Ok(dir) = std::env::var("EMPC_DUMP") {
        std::fs::write(format!("{dir}/{name}.json"), prob.to_json_string()).unwrap();
    }
    let sol = solve(prob, &Settings::default()).unwrap();
    let ctl = build_controller(
        prob,
        &sol,
        &TreeSettings {
            outputs: Outputs::First(4),
            ..TreeSettings::default()
        },
    )
    .unwrap();
    eprintln!(
        "{name} (p = {}, n = {}): {} regions, {} distinct laws, solve {:.4} s, tree depth {}, {} nodes, {} bytes (f32)",
        prob.p(),
        prob.n(),
        sol.regions.len(),
        ctl.stats.distinct_laws,
        sol.stats.solve_seconds,
        ctl.stats.depth,
        ctl.stats.nodes,
        ctl.tables.bytes(4)
    );
    assert_eq!(ctl.stats.ambiguous_leaves, 0, "{name}");
    let compact = build_compact(
        prob,
        &sol,
        &TreeSettings {
            outputs: Outputs::First(4),
            ..TreeSettings::default()
        },
    )
    .unwrap();
    eprintln!(
        "{name} compact layout (one tree per output): distinct laws per output {:?}, depth per output {:?} (max {}), nodes per output {:?} ({} in all), {} distinct hyperplanes, {} rows, {} bytes (f32) vs {} bytes in the default layout",
        compact
            .per_output
            .iter()
            .map(|s| s.distinct_laws)
            .collect::<Vec<_>>(),
        compact
            .per_output
            .iter()
            .map(|s| s.depth)
            .collect::<Vec<_>>(),
        compact.depth,
        compact
            .per_output
            .iter()
            .map(|s| s.nodes)
            .collect::<Vec<_>>(),
        compact.tables.nodes.len(),
        compact.hyperplanes,
        compact.tables.rows.len() / (prob.p() + 1),
        compact.tables.bytes(4),
        ctl.tables.bytes(4)
    );
    assert_eq!(compact.ambiguous_leaves, 0, "{name}");
    let tc = compact.tables.tables();
    let mut zc = vec![0.0; 4];
    let mut mismatches_compact = 0usize;
    let mut worst_compact = 0.0_f64;
    let settings = QpSettings {
        tolerance: 1e-11,
        max_iter: 400,
        ..QpSettings::default()
    };
    let mut reference = ReferenceSolver::new(prob, settings).unwrap();
    let t = ctl.tables.tables();
    let p = prob.p();
    let mut rng = Rng::new(11);
    let mut scratch = vec![0.0; p];
    let mut z = vec![0.0; 4];
    let (mut worst, mut worst_tree) = (0.0_f64, 0.0_f64);
    let mut mismatches = 0usize;
    let mut worst_raw = 0.0_f64;
    for _ in 0..samples {
        let theta: Vec<f64> = (0..p)
            .map(|j| {
                let (lo, hi) = (prob.theta_lb[j], prob.theta_ub[j]);
                lo + (hi - lo) * 0.5 * (rng.sym() + 1.0)
            })
            .collect();
        let ri = sol.locate(&theta, 1e-7);
        assert!(ri.is_some(), "{name}: theta {theta:?} not covered");
        let zr = sol.regions[ri.unwrap()].z(&theta);
        let th = DVector::from_column_slice(&theta);
        let qp = reference.solve(&th).unwrap();
        let raw = qp.z;
        let e = evaluate_with(&t, &theta, &mut scratch, &mut z).unwrap();
        assert!(!e.outside, "{name}: theta {theta:?} flagged outside");
        let scale = 1.0 + raw.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        worst_raw = (0..4).fold(worst_raw, |s, j| s.max((z[j] - raw[j]).abs() / scale));
        let zp = brute_force_kkt(prob, &th);
        let dev = (0..4).fold(0.0_f64, |s, j| s.max((z[j] - zp[j]).abs() / scale));
        worst = worst.max(dev);
        worst_tree = (0..4).fold(worst_tree, |s, j| s.max((zr[j] - z[j]).abs() / scale));
        if dev > 1e-8 {
            mismatches += 1;
        }
        let ec = evaluate_with(&tc, &theta, &mut scratch, &mut zc).unwrap();
        assert!(
            !ec.outside,
            "{name}: theta {theta:?} flagged outside (compact)"
        );
        let devc = (0..4).fold(0.0_f64, |s, j| s.max((zc[j] - zp[j]).abs() / scale));
        worst_compact = worst_compact.max(devc);
        if devc > 1e-8 {
            mismatches_compact += 1;
        }
    }
    eprintln!(
        "{name}: {samples} parameters, worst relative deviation of the tree from the brute-force KKT optimum {worst:.2e}, from clarabel {worst_raw:.2e}, from the region law {worst_tree:.2e}, {mismatches} mismatches"
    );
    eprintln!(
        "{name} compact layout: worst relative deviation from the brute-force KKT optimum {worst_compact:.2e}, {mismatches_compact} mismatches"
    );
    assert_eq!(mismatches, 0, "{name}: worst deviation {worst:e}");
    assert_eq!(
        mismatches_compact, 0,
        "{name}: compact layout, worst deviation {worst_compact:e}"
    );
    assert!(worst_raw <= 1e-6, "{name}: tree vs clarabel {worst_raw:e}");

    assert!(
        worst_tree <= 1e-9,
        "{name}: tree vs region law {worst_tree:e}"
    );
    Report {
        regions: sol.regions.len(),
        laws: ctl.stats.distinct_laws,
        bytes_f32: ctl.tables.bytes(4),
        compact_bytes_f32: compact.tables.bytes(4),
    }
}

#[test]
fn thesis_sized_blackbox_tree_is_exact() {
    let model = blackbox_model();
    let (q1, q2) = default_weights();
    let prob = tricopter_problem(&model, ProblemSize::Thesis, q1, q2)
        .unwrap()
        .to_mpqp();
    assert_eq!((prob.p(), prob.n()), (9, 4));
    let r = check("thesis-blackbox5", &prob, 10_000);
    assert!(
        r.regions > 1 && r.laws > 1,
        "a trivial law would test nothing"
    );
    eprintln!(
        "thesis-sized tables in f32: {} bytes (default layout), {} bytes (compact layout, target < 8192)",
        r.bytes_f32, r.compact_bytes_f32
    );
}

#[test]
fn design_model_tree_is_exact() {
    let model = design_model().unwrap();
    let (q1, q2) = default_weights();
    let prob = tricopter_problem(&model, ProblemSize::Thesis, q1, q2)
        .unwrap()
        .to_mpqp();
    check("thesis-design8", &prob, 10_000);
}
