//! The wide (`u32`) table layout: the same tree as the `u16` layout node
//! for node, bit-identical answers, a solution-file round trip, exported
//! Rust source that compiles (included here) and evaluates alike, corrupted
//! wide tables rejected, and a tree beyond the 32767 nodes of the `u16`
//! codes evaluated against a closed form.

mod common;

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::eval::{TreeTables, WIDE_LEAF, WIDE_NO_ROW};
use kestrel_empc::export::{
    ExportScalar, ExportTables, TableFormat, check_tables, read_tables, rust_source, solution_json,
    table_formats,
};
use kestrel_empc::mpqp::Rng;
use kestrel_empc::tree::{AnyTables, OwnedTables, TreeLayout, TreeMethod, WideTables, build_any};
use kestrel_empc::{
    EmpcError, Outputs, Settings, TreeSettings, build_controller, evaluate, evaluate_with, solve,
};

mod wide_f64 {
    include!("generated/box2_wide_f64.rs");
}
mod wide_f32 {
    include!("generated/box2_wide_f32.rs");
}
mod narrow_f32 {
    include!("generated/box2_f32.rs");
}

fn box2() -> MpqpProblem {
    MpqpProblem::from_json_str(include_str!("generated/box2.json")).unwrap()
}

fn wide_settings(layout: TreeLayout) -> TreeSettings {
    TreeSettings {
        layout,
        ..TreeSettings::default()
    }
}

/// Random parameters in the box scaled by `spread` about its centre
/// (`spread` > 1: some outside).
fn thetas(prob: &MpqpProblem, n: usize, spread: f64, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            (0..prob.p())
                .map(|j| {
                    let (lo, hi) = (prob.theta_lb[j], prob.theta_ub[j]);
                    0.5 * (lo + hi) + 0.5 * (hi - lo) * spread * rng.sym()
                })
                .collect()
        })
        .collect()
}

/// Both layouts of the same tree at every parameter: the same law, flag,
/// steps and `z` bit for bit (f64 and f32).
fn assert_bit_identical(narrow: &OwnedTables<f64>, wide: &WideTables<f64>, ths: &[Vec<f64>]) {
    let (k, p) = (narrow.n_outputs, narrow.n_params);
    let (n32, w32) = (narrow.cast::<f32>(), wide.cast::<f32>());
    let (mut zn, mut zw, mut s) = (vec![0.0; k], vec![0.0; k], vec![0.0; p]);
    let (mut zn32, mut zw32, mut s32) = (vec![0.0f32; k], vec![0.0f32; k], vec![0.0f32; p]);
    let mut outside = 0;
    for th in ths {
        let en = evaluate_with(&narrow.tables(), th, &mut s, &mut zn).unwrap();
        let ew = evaluate_with(&wide.tables(), th, &mut s, &mut zw).unwrap();
        assert_eq!(
            (u32::from(en.law), en.outside, en.steps),
            (ew.law, ew.outside, ew.steps)
        );
        assert_eq!(
            zn.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            zw.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        outside += usize::from(en.outside);
        let th32: Vec<f32> = th.iter().map(|&v| v as f32).collect();
        let en = evaluate_with(&n32.tables(), &th32, &mut s32, &mut zn32).unwrap();
        let ew = evaluate_with(&w32.tables(), &th32, &mut s32, &mut zw32).unwrap();
        assert_eq!(u32::from(en.law), ew.law);
        assert_eq!(
            zn32.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            zw32.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
    assert!(outside > 0, "some parameters lie outside the box");
}

#[test]
fn forced_wide_layout_is_the_same_tree_with_bit_identical_answers() {
    for (name, prob, outputs, method) in [
        ("box2", box2(), Outputs::All, TreeMethod::Auto),
        (
            "thesis-sized",
            kestrel_empc::testing::thesis_sized(1),
            Outputs::First(4),
            TreeMethod::Sampled,
        ),
    ] {
        let sol = solve(&prob, &Settings::default()).unwrap();
        let base = TreeSettings {
            outputs,
            method,
            ..TreeSettings::default()
        };
        let narrow = build_controller(&prob, &sol, &base).unwrap();
        let auto = build_any(&prob, &sol, &base).unwrap();
        let wide = build_any(
            &prob,
            &sol,
            &TreeSettings {
                layout: TreeLayout::Wide,
                ..base.clone()
            },
        )
        .unwrap();
        // Auto keeps u16 for a tree that fits; Wide is the same tree widened.
        assert_eq!(
            auto.tables,
            AnyTables::Narrow(narrow.tables.clone()),
            "{name}"
        );
        let AnyTables::Wide(w) = &wide.tables else {
            panic!("{name}: TreeLayout::Wide gave u16 tables");
        };
        assert_eq!(w, &narrow.tables.widen(), "{name}");
        assert_eq!(w.narrow().as_ref(), Some(&narrow.tables), "{name}");
        assert_eq!(wide.region_law, narrow.region_law);
        assert_eq!(wide.stats.nodes, narrow.stats.nodes);
        // 4 bytes per index instead of 2, the numbers alike.
        let t = &narrow.tables;
        let idx = 4 * t.nodes.len() + t.laws.len() + 2 * t.bounds.len();
        assert_eq!(w.bytes(4), t.bytes(4) + 2 * idx);
        assert_bit_identical(t, w, &thetas(&prob, 10_000, 1.2, 7));
    }
}

#[test]
fn wide_solution_file_round_trips_and_the_exported_source_evaluates_alike() {
    let prob = box2();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let narrow = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    let wide = build_any(&prob, &sol, &wide_settings(TreeLayout::Wide)).unwrap();
    let AnyTables::Wide(w) = &wide.tables else {
        panic!("not wide")
    };
    // The exported source is what the exporter writes today.
    for (scalar, golden) in [
        (
            ExportScalar::F64,
            include_str!("generated/box2_wide_f64.rs"),
        ),
        (
            ExportScalar::F32,
            include_str!("generated/box2_wide_f32.rs"),
        ),
    ] {
        assert_eq!(
            rust_source(w, scalar).unwrap(),
            golden,
            "the golden file is stale: run `kestrel codegen`"
        );
    }
    // Solution file: the wide tables come back bit for bit, marked u32;
    // the u16 reader refuses them with a pointer to the reader that takes them.
    let text = solution_json(&sol, &wide, false);
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["tables"]["index"], "u32");
    assert_eq!(v["tree"]["bytes"], w.bytes(4));
    assert_eq!(v["tree"]["index_bytes"], 4);
    assert_eq!(table_formats(&text).unwrap(), [TableFormat::Wide]);
    assert_eq!(wide.tables.format(), TableFormat::Wide);
    assert_eq!(w.format(), TableFormat::Wide);
    assert_eq!(narrow.tables.format(), TableFormat::Narrow);
    assert_eq!(read_tables::<AnyTables>(&text).unwrap(), wide.tables);
    assert_eq!(&read_tables::<WideTables<f64>>(&text).unwrap(), w);
    let err = read_tables::<OwnedTables<f64>>(&text)
        .unwrap_err()
        .to_string();
    assert!(err.contains("WideTables or AnyTables"), "{err}");
    // A u16 file reads as the u16 layout, unchanged.
    let text16 = solution_json(&sol, &narrow, false);
    assert_eq!(table_formats(&text16).unwrap(), [TableFormat::Narrow]);
    let err = read_tables::<WideTables<f64>>(&text16)
        .unwrap_err()
        .to_string();
    assert!(err.contains("OwnedTables or AnyTables"), "{err}");
    assert_eq!(
        read_tables::<AnyTables>(&text16).unwrap(),
        AnyTables::Narrow(narrow.tables.clone())
    );
    // The `static` wide tables against the u16 tables (f64 from the
    // solution, f32 from the committed u16 source), inside and outside.
    let mut rng = Rng::new(3);
    for _ in 0..10_000 {
        let th = [3.5 * rng.sym(), 3.5 * rng.sym()];
        let (mut want, mut z) = ([0.0f64; 2], [0.0f64; 2]);
        let e_ref = evaluate(&narrow.tables.tables(), &th, &mut want).unwrap();
        let e = evaluate(&wide_f64::TABLES, &th, &mut z).unwrap();
        assert_eq!((u32::from(e_ref.law), e_ref.outside), (e.law, e.outside));
        assert_eq!(z.map(f64::to_bits), want.map(f64::to_bits));
        let th32 = [th[0] as f32, th[1] as f32];
        let (mut want32, mut z32) = ([0.0f32; 2], [0.0f32; 2]);
        evaluate(&narrow_f32::TABLES, &th32, &mut want32).unwrap();
        evaluate(&wide_f32::TABLES, &th32, &mut z32).unwrap();
        assert_eq!(z32.map(f32::to_bits), want32.map(f32::to_bits));
    }
}

#[test]
fn corrupted_wide_tables_are_rejected() {
    let prob = box2();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let wide = build_any(&prob, &sol, &wide_settings(TreeLayout::Wide)).unwrap();
    let good: serde_json::Value = serde_json::from_str(&solution_json(&sol, &wide, false)).unwrap();
    let nn = wide.tables.n_nodes();
    let cases: Vec<(&str, serde_json::Value, &str)> = vec![
        ("nodes/0/0", serde_json::json!(999), "node 0"),
        ("nodes/0/0", serde_json::json!(-1), "tables.nodes[0][0]"),
        ("nodes/0/0", serde_json::json!(5e9), "tables.nodes[0][0]"),
        ("nodes/0/2", serde_json::json!(0), "not after it"),
        ("nodes/0/3", serde_json::json!(nn), "node 0"),
        (
            "root",
            serde_json::json!(u64::from(WIDE_LEAF) | 999),
            "root",
        ),
        ("laws/0/0", serde_json::json!(99_999), "a law uses row"),
        ("bounds/0/0", serde_json::json!(999), "output bound"),
        ("theta_lb/0", serde_json::json!(9), "theta_lb exceeds"),
        ("index", serde_json::json!("u64"), "tables.index"),
    ];
    common::assert_corruptions_rejected(&good, "tables", cases, read_tables::<AnyTables>);
}

/// A chain of `n` nodes over one parameter: node `i` sends theta <= c_i
/// to law `i`, the rest on; law `i` outputs the constant `i`. So `z` is the
/// number of thresholds below theta, a closed form.
fn chain(n: usize) -> (WideTables<f64>, Vec<f64>) {
    let c: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    let mut rows = Vec::new();
    for &ci in &c {
        rows.extend([1.0, -ci]); // theta - c_i <= 0
    }
    for i in 0..=n {
        rows.extend([0.0, i as f64]); // law i: z = i
    }
    let nodes = (0..n)
        .map(|i| {
            let next = if i + 1 < n {
                (i + 1) as u32
            } else {
                WIDE_LEAF | n as u32
            };
            [i as u32, WIDE_NO_ROW, WIDE_LEAF | i as u32, next]
        })
        .collect();
    let t = WideTables {
        n_params: 1,
        n_outputs: 1,
        root: 0,
        nodes,
        laws: (0..=n).map(|i| (n + i) as u32).collect(),
        rows,
        hull: vec![],
        theta_lb: vec![-1.0],
        theta_ub: vec![2.0],
        bounds: vec![[WIDE_NO_ROW, WIDE_NO_ROW]],
    };
    (t, c)
}

#[test]
fn a_tree_beyond_the_u16_codes_evaluates_exactly() {
    let n = 40_000; // more nodes than the 32767 the u16 codes address
    let (t, c) = chain(n);
    check_tables(&t).unwrap();
    assert!(t.narrow().is_none(), "40000 nodes do not fit u16");
    let mut rng = Rng::new(1);
    let mut z = [0.0];
    for _ in 0..300 {
        let th = 1.5 * rng.sym() + 0.5;
        let e = evaluate(&t.tables(), &[th], &mut z).unwrap();
        let clamped = th.clamp(-1.0, 2.0);
        let want = c.iter().filter(|&&ci| ci < clamped).count();
        assert_eq!(z[0], want as f64, "theta {th}");
        assert_eq!(e.law as usize, want);
        assert_eq!(e.outside, !(-1.0..=2.0).contains(&th));
    }
    // The exporter writes it (u32 arrays).
    let src = rust_source(&t, ExportScalar::F32).unwrap();
    assert!(src.contains(&format!("pub static NODES: [[u32; 4]; {n}]")));
    assert!(src.contains("WideSliceTables"));
}

#[test]
fn wide_evaluation_errors_are_values() {
    let (mut t, _) = chain(3);
    let mut z = [0.0];
    assert!(matches!(
        evaluate(&t.tables(), &[f64::NAN], &mut z),
        Err(kestrel_core::Error::NonFinite)
    ));
    t.nodes[1][3] = 0; // a cycle
    assert_eq!(
        evaluate(&t.tables(), &[0.9], &mut z),
        Err(kestrel_core::Error::OutOfRange)
    );
    assert!(check_tables(&t).is_err());
    let (mut t, _) = chain(3);
    t.laws[3] = 999; // a law past the rows
    assert_eq!(
        evaluate(&t.tables(), &[0.9], &mut z),
        Err(kestrel_core::Error::OutOfRange)
    );
}

#[test]
fn node_caps_hold_in_every_layout() {
    let prob = kestrel_empc::testing::thesis_sized(1);
    let sol = solve(&prob, &Settings::default()).unwrap();
    for layout in [TreeLayout::Auto, TreeLayout::Narrow, TreeLayout::Wide] {
        let s = TreeSettings {
            outputs: Outputs::First(4),
            method: TreeMethod::Sampled,
            max_nodes: 20,
            layout,
            ..TreeSettings::default()
        };
        let e = build_any(&prob, &sol, &s).unwrap_err();
        assert!(matches!(e, EmpcError::TooLarge(_)), "{layout:?}: {e}");
        assert!(e.to_string().contains("max_nodes"), "{e}");
    }
    // The default cap allows wide trees, finitely.
    let d = TreeSettings::default().max_nodes;
    assert!(d > kestrel_empc::tree::MAX_NODES && d <= kestrel_empc::tree::WIDE_MAX_NODES);
}

/// Tables that hide [`TreeTables::row_slice`] (as a flash accessor does):
/// the evaluation reads every entry through `row`.
struct EntryOnly<T>(T);

impl<S: kestrel_core::Scalar, I: kestrel_empc::eval::TreeIndex, T: TreeTables<S, I>>
    TreeTables<S, I> for EntryOnly<T>
{
    fn n_params(&self) -> usize {
        self.0.n_params()
    }
    fn n_outputs(&self) -> usize {
        self.0.n_outputs()
    }
    fn n_nodes(&self) -> usize {
        self.0.n_nodes()
    }
    fn root(&self) -> I {
        self.0.root()
    }
    fn node(&self, i: usize) -> Option<[I; 4]> {
        self.0.node(i)
    }
    fn law(&self, law: usize, out: usize) -> Option<I> {
        self.0.law(law, out)
    }
    fn row(&self, r: usize, j: usize) -> Option<S> {
        self.0.row(r, j)
    }
    fn n_hull(&self) -> usize {
        self.0.n_hull()
    }
    fn hull(&self, i: usize, j: usize) -> Option<S> {
        self.0.hull(i, j)
    }
    fn theta_bounds(&self, j: usize) -> Option<(S, S)> {
        self.0.theta_bounds(j)
    }
    fn output_bounds(&self, out: usize) -> Option<[I; 2]> {
        self.0.output_bounds(out)
    }
}

#[test]
fn row_slices_give_the_same_bits_as_entry_reads() {
    use kestrel_core::{Q16, Scalar};
    let prob = kestrel_empc::testing::thesis_sized(1);
    let sol = solve(&prob, &Settings::default()).unwrap();
    let s = TreeSettings {
        outputs: Outputs::First(4),
        ..TreeSettings::default()
    };
    let t = build_controller(&prob, &sol, &s).unwrap().tables;
    let w = t.widen();
    fn check<S: Scalar, I: kestrel_empc::eval::TreeIndex, T: TreeTables<S, I> + Copy>(
        t: T,
        ths: &[Vec<f64>],
    ) {
        let (mut a, mut b) = (vec![S::ZERO; t.n_outputs()], vec![S::ZERO; t.n_outputs()]);
        let mut scratch = vec![S::ZERO; t.n_params()];
        for th in ths {
            let th: Vec<S> = th.iter().map(|&v| S::from_f64(v)).collect();
            let ea = evaluate_with(&t, &th, &mut scratch, &mut a).unwrap();
            let eb = evaluate_with(&EntryOnly(t), &th, &mut scratch, &mut b).unwrap();
            assert_eq!(ea, eb);
            assert!(
                a.iter()
                    .zip(&b)
                    .all(|(x, y)| x.to_f64().to_bits() == y.to_f64().to_bits())
            );
        }
    }
    let ths = thetas(&prob, 3000, 1.2, 17);
    check(t.tables(), &ths);
    check(t.cast::<f32>().tables(), &ths);
    check(t.cast::<Q16>().tables(), &ths);
    check(w.tables(), &ths);
}
