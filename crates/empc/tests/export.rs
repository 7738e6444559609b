//! The exported Rust source compiles (it is included here), is what the
//! exporter writes today, and its `static` tables evaluate like the solution.
//! The golden files `tests/generated/box2_*.rs` are written by `kestrel
//! codegen` (kestrel-tricopter's `codegen::golden::empc_files`, the same
//! export of the same problem); this test only compares.

mod common;

use kestrel_core::formats::MpqpProblem;
use kestrel_core::{Q16, Scalar};
use kestrel_empc::export::{ExportScalar, rust_source};
use kestrel_empc::mpqp::Rng;
use kestrel_empc::{Settings, TreeSettings, build_controller, evaluate, solve};

mod f32_tables {
    include!("generated/box2_f32.rs");
}
mod q16_tables {
    include!("generated/box2_q16.rs");
}
mod compact_f32 {
    include!("generated/box2_compact_f32.rs");
}
mod compact_f64 {
    include!("generated/box2_compact_f64.rs");
}
mod compact_q16 {
    include!("generated/box2_compact_q16.rs");
}

#[test]
fn exported_tables_are_current_and_evaluate_like_the_solution() {
    let prob = MpqpProblem::from_json_str(include_str!("generated/box2.json")).unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    assert_eq!(
        rust_source(&ctl.tables, ExportScalar::F32).unwrap(),
        include_str!("generated/box2_f32.rs"),
        "the golden file is stale: run `kestrel codegen`"
    );
    assert_eq!(
        rust_source(&ctl.tables, ExportScalar::Q16).unwrap(),
        include_str!("generated/box2_q16.rs")
    );
    let mut rng = Rng::new(5);
    for _ in 0..2000 {
        let th = [3.0 * rng.sym(), 3.0 * rng.sym()];
        let r = sol.locate(&th, 1e-9).unwrap();
        let want = sol.regions[r].z(&th);
        let mut z = [0.0f32; 2];
        let e = evaluate(&f32_tables::TABLES, &[th[0] as f32, th[1] as f32], &mut z).unwrap();
        assert!(!e.outside);
        let mut zq = [Q16::ZERO; 2];
        evaluate(
            &q16_tables::TABLES,
            &[Q16::from_f64(th[0]), Q16::from_f64(th[1])],
            &mut zq,
        )
        .unwrap();
        for j in 0..2 {
            assert!((z[j] as f64 - want[j]).abs() < 1e-5);
            assert!(
                (zq[j].to_f64() - want[j]).abs() < 1e-3,
                "{} vs {}",
                zq[j].to_f64(),
                want[j]
            );
        }
    }
}

#[test]
fn solution_file_with_compact_layout_reports_its_bytes_and_tables() {
    use kestrel_empc::build_compact;
    use kestrel_empc::export::{SolutionTables, solution_json};
    let prob = MpqpProblem::from_json_str(include_str!("generated/box2.json")).unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    let compact = build_compact(&prob, &sol, &TreeSettings::default()).unwrap();
    let plain: serde_json::Value = serde_json::from_str(&solution_json(&sol, &ctl, false)).unwrap();
    let with: serde_json::Value = serde_json::from_str(&solution_json(
        &sol,
        SolutionTables::from(&ctl).with_compact(&compact),
        false,
    ))
    .unwrap();
    // The default layout's keys are unchanged; the compact ones are added.
    for key in ["tree", "tables", "regions", "distinct_laws"] {
        assert_eq!(plain[key], with[key], "{key}");
    }
    assert!(plain.get("tree_compact").is_none());
    let t = &with["tree_compact"];
    assert_eq!(t["bytes"], compact.tables.bytes(4));
    assert_eq!(t["nodes"], compact.tables.nodes.len());
    let nodes = with["compact_tables"]["nodes"].as_array().unwrap();
    assert_eq!(nodes.len(), compact.tables.nodes.len());
    // Counted bytes: 4 per number, 6 per node, 2 per other index.
    let c = &compact.tables;
    let numbers = c.rows.len() + c.hull.len() + c.theta_lb.len() + c.theta_ub.len();
    assert_eq!(
        c.bytes(4),
        4 * numbers + 6 * c.nodes.len() + 2 * (c.roots.len() + 2 * c.bounds.len())
    );
    // The compact tables evaluate like the solution.
    let mut rng = Rng::new(9);
    for _ in 0..2000 {
        let th = [3.0 * rng.sym(), 3.0 * rng.sym()];
        let r = sol.locate(&th, 1e-9).unwrap();
        let want = sol.regions[r].z(&th);
        let mut z = [0.0f64; 2];
        let e = evaluate(&c.tables(), &th, &mut z).unwrap();
        assert!(!e.outside);
        assert!((z[0] - want[0]).abs() < 1e-9 && (z[1] - want[1]).abs() < 1e-9);
    }
}

#[test]
fn exported_compact_tables_are_current_round_trip_and_equal_the_default_tree() {
    use kestrel_empc::CompactTables;
    use kestrel_empc::build_compact;
    use kestrel_empc::export::{
        SolutionTables, TableFormat, read_tables, solution_json, table_formats,
    };
    let prob = MpqpProblem::from_json_str(include_str!("generated/box2.json")).unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    let compact = build_compact(&prob, &sol, &TreeSettings::default()).unwrap();
    for (scalar, golden) in [
        (
            ExportScalar::F32,
            include_str!("generated/box2_compact_f32.rs"),
        ),
        (
            ExportScalar::F64,
            include_str!("generated/box2_compact_f64.rs"),
        ),
        (
            ExportScalar::Q16,
            include_str!("generated/box2_compact_q16.rs"),
        ),
    ] {
        assert_eq!(
            rust_source(&compact.tables, scalar).unwrap(),
            golden,
            "the golden file is stale: run `kestrel codegen`"
        );
    }
    // Solution file -> compact tables -> source: the same tables, bit for bit.
    let text = solution_json(
        &sol,
        SolutionTables::from(&ctl).with_compact(&compact),
        false,
    );
    assert_eq!(
        table_formats(&text).unwrap(),
        [TableFormat::Narrow, TableFormat::Compact]
    );
    assert_eq!(
        table_formats(&solution_json(&sol, &ctl, false)).unwrap(),
        [TableFormat::Narrow]
    );
    let back: CompactTables<f64> = read_tables(&text).unwrap();
    assert_eq!(back, compact.tables);
    // The `static` tables (f64, f32, Q16) against the default tree (f64)
    // on 10^4 parameters, some outside the box (flagged alike).
    let mut rng = Rng::new(11);
    let mut outside = 0;
    for _ in 0..10_000 {
        let th = [3.5 * rng.sym(), 3.5 * rng.sym()];
        let mut want = [0.0f64; 2];
        let e_ref = evaluate(&ctl.tables.tables(), &th, &mut want).unwrap();
        let mut z = [0.0f64; 2];
        let e = evaluate(&compact_f64::TABLES, &th, &mut z).unwrap();
        assert_eq!(e.outside, e_ref.outside);
        outside += usize::from(e.outside);
        let mut z32 = [0.0f32; 2];
        let e32 = evaluate(
            &compact_f32::TABLES,
            &[th[0] as f32, th[1] as f32],
            &mut z32,
        )
        .unwrap();
        assert_eq!(e32.outside, e_ref.outside);
        let mut zq = [Q16::ZERO; 2];
        evaluate(
            &compact_q16::TABLES,
            &[Q16::from_f64(th[0]), Q16::from_f64(th[1])],
            &mut zq,
        )
        .unwrap();
        for j in 0..2 {
            assert!((z[j] - want[j]).abs() <= 1e-12, "{th:?}: {z:?} vs {want:?}");
            assert!((z32[j] as f64 - want[j]).abs() < 1e-5, "{th:?}");
            assert!((zq[j].to_f64() - want[j]).abs() < 1e-3, "{th:?}");
        }
    }
    assert!(outside > 0, "some samples lie outside the box");
}

#[test]
fn corrupted_compact_tables_are_rejected() {
    use kestrel_empc::CompactTables;
    use kestrel_empc::build_compact;
    use kestrel_empc::export::{SolutionTables, read_tables, solution_json};
    let compact_tables_from_json = read_tables::<CompactTables<f64>>;
    let prob = MpqpProblem::from_json_str(include_str!("generated/box2.json")).unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    let compact = build_compact(&prob, &sol, &TreeSettings::default()).unwrap();
    let good: serde_json::Value = serde_json::from_str(&solution_json(
        &sol,
        SolutionTables::from(&ctl).with_compact(&compact),
        false,
    ))
    .unwrap();
    let nn = compact.tables.nodes.len();
    let cases: Vec<(&str, serde_json::Value, &str)> = vec![
        (
            "nodes/0/0",
            serde_json::json!(300),
            "compact_tables.nodes[0][0]",
        ),
        ("nodes/0/0", serde_json::json!(200), "node 0"),
        ("nodes/0/2", serde_json::json!(0), "not after it"),
        ("nodes/0/3", serde_json::json!(nn), "node 0"),
        ("roots/0", serde_json::json!(0x8000 | 999), "root"),
        ("roots/0", serde_json::json!(-1), "compact_tables.roots[0]"),
        ("bounds/0/0", serde_json::json!(999), "output bound"),
        ("theta_lb/0", serde_json::json!(9), "theta_lb exceeds"),
    ];
    common::assert_corruptions_rejected(&good, "compact_tables", cases, compact_tables_from_json);
    let mut v = good.clone();
    v.as_object_mut().unwrap().remove("compact_tables");
    let err = compact_tables_from_json(&v.to_string())
        .unwrap_err()
        .to_string();
    assert!(err.contains("--compact"), "{err}");
    let mut v = good;
    v["compact_tables"]["roots"] = serde_json::json!([0]);
    let err = compact_tables_from_json(&v.to_string())
        .unwrap_err()
        .to_string();
    assert!(err.contains("roots"), "{err}");
}
