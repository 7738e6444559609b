//! Writes the golden exported tables used by `tests/export.rs`:
//! `cargo run -p kestrel-empc --example golden`.
use kestrel_empc::export::{ExportScalar, rust_source};
use kestrel_empc::{Settings, TreeSettings, build_controller, solve};

fn main() {
    let prob = kestrel_core::formats::MpqpProblem::from_json_str(include_str!(
        "../tests/generated/box2.json"
    ))
    .unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/generated");
    std::fs::write(
        format!("{dir}/box2_f32.rs"),
        rust_source(&ctl.tables, ExportScalar::F32).unwrap(),
    )
    .unwrap();
    std::fs::write(
        format!("{dir}/box2_q16.rs"),
        rust_source(&ctl.tables, ExportScalar::Q16).unwrap(),
    )
    .unwrap();
}
