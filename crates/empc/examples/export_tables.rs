//! Writes an explicit controller's tables as Rust source for `no_std`
//! firmware (`static` arrays and a `TABLES` for `kestrel_empc::evaluate`):
//! `cargo run -p kestrel-empc --example export_tables [f32|f64|q16]`.
//!
//! The problem is `min 1/2 z^2 + theta z` subject to `|z| <= 1` over
//! `theta` in `[-2, 2]` (`z = clamp(-theta)`); the firmware includes the
//! printed file and calls `evaluate(&TABLES, &theta, &mut z)`.
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::export::{ExportScalar, rust_source};
use kestrel_empc::{Settings, TreeSettings, build_controller, solve};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scalar = match std::env::args().nth(1).as_deref() {
        None | Some("f32") => ExportScalar::F32,
        Some("f64") => ExportScalar::F64,
        Some("q16") => ExportScalar::Q16,
        Some(other) => return Err(format!("unknown scalar {other:?} (f32, f64 or q16)").into()),
    };
    let problem = MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1", "H": [[1]], "F": [[1]],
            "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
            "theta_lb": [-2], "theta_ub": [2]}"#,
    )?;
    let solution = solve(&problem, &Settings::default())?;
    // Without clipping, so that the tree has nodes to show (with it, one
    // clamped law serves the whole box).
    let settings = TreeSettings {
        clipping: false,
        ..TreeSettings::default()
    };
    let controller = build_controller(&problem, &solution, &settings)?;
    print!("{}", rust_source(&controller.tables, scalar)?);
    Ok(())
}
