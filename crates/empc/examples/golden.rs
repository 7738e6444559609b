//! Writes the golden exported tables used by `tests/export.rs` and
//! `tests/wide.rs`:
//! `cargo run -p kestrel-empc --example golden`.
use kestrel_empc::export::{ExportScalar, rust_source, rust_source_compact, rust_source_wide};
use kestrel_empc::{Settings, TreeSettings, build_compact, build_controller, solve};

fn main() {
    let prob = kestrel_core::formats::MpqpProblem::from_json_str(include_str!(
        "../tests/generated/box2.json"
    ))
    .unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    let compact = build_compact(&prob, &sol, &TreeSettings::default()).unwrap();
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/generated");
    for (name, scalar) in [
        ("f32", ExportScalar::F32),
        ("q16", ExportScalar::Q16),
        ("f64", ExportScalar::F64),
    ] {
        if scalar != ExportScalar::F64 {
            std::fs::write(
                format!("{dir}/box2_{name}.rs"),
                rust_source(&ctl.tables, scalar).unwrap(),
            )
            .unwrap();
        }
        if scalar != ExportScalar::Q16 {
            // The same tree in the wide (u32) layout.
            std::fs::write(
                format!("{dir}/box2_wide_{name}.rs"),
                rust_source_wide(&ctl.tables.widen(), scalar).unwrap(),
            )
            .unwrap();
        }
        std::fs::write(
            format!("{dir}/box2_compact_{name}.rs"),
            rust_source_compact(&compact.tables, scalar).unwrap(),
        )
        .unwrap();
    }
}
