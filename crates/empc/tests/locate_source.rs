//! The candidate-list tables as Rust source: the committed
//! `tests/generated/box2_lists_f32.rs` (the lists of `generated/box2.json`,
//! `leaf_regions` 1) is what `ListTables::rust_source` writes today, it
//! compiles (it is included here), and its `static` tables evaluate like
//! the in-memory ones. `kestrel codegen` writes the file (and `kestrel
//! codegen --check` compares it in CI).

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::export::ExportScalar;
use kestrel_empc::locate::{LocateSettings, build_lists};
use kestrel_empc::{Settings, evaluate_lists, solve};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

mod lists_f32 {
    include!("generated/box2_lists_f32.rs");
}

#[test]
fn list_source_is_current_and_evaluates_like_the_tables() {
    let prob = MpqpProblem::from_json_str(include_str!("generated/box2.json")).unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let settings = LocateSettings {
        leaf_regions: 1,
        ..LocateSettings::default()
    };
    let c = build_lists(&prob, &sol, &settings, &mut |_| {}).unwrap();
    assert!(c.stats.nodes > 0, "{:?}", c.stats);
    let narrow = c.tables.narrow().unwrap();
    let text = narrow.rust_source(ExportScalar::F32).unwrap();
    assert_eq!(
        text,
        include_str!("generated/box2_lists_f32.rs"),
        "the golden file is stale: run `kestrel codegen`"
    );
    assert!(narrow.rust_source(ExportScalar::Q16).is_ok());
    let mine = narrow.cast::<f32>();
    let mut rng = SplitMix64::seed_from_u64(3);
    let (mut z, mut zs, mut s1, mut s2) = ([0.0f32; 2], [0.0f32; 2], [0.0f32; 2], [0.0f32; 2]);
    for _ in 0..10_000 {
        let th = [
            (7.0 * rng.random::<f64>() - 3.5) as f32,
            (7.0 * rng.random::<f64>() - 3.5) as f32,
        ];
        let a = evaluate_lists(&mine.tables(), &th, &mut s1, &mut z).unwrap();
        let b = evaluate_lists(&lists_f32::TABLES, &th, &mut s2, &mut zs).unwrap();
        assert_eq!((a, z), (b, zs));
        let want = sol.first_outputs_at(&th.map(f64::from), 2);
        if let (Some(want), false) = (want, a.outside) {
            for (x, y) in z.iter().zip(&want) {
                assert!((f64::from(*x) - y).abs() <= 1e-5 * (1.0 + y.abs()));
            }
        }
    }
}
