//! The exported firmware tables compile and equal the design's tables:
//! `tests/data/fgm_q16.rs` is `export_rust` of the problem
//! `tests/data/fgm_problem.json` (written by `kestrel codegen`, which
//! kestrel-tricopter's `codegen::golden::fgm_file` does with the same
//! settings) and included here as code.

use kestrel_core::formats::MpqpProblem;
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::{
    BoxQp, ExportScalar, FgmDesign, FgmSettings, FgmWorkspace, Momentum, Preconditioner,
    export_rust,
};

mod generated {
    include!("data/fgm_q16.rs");
}

/// The problem of the golden table (`kestrel codegen` reads the same file).
const PROBLEM: &str = include_str!("data/fgm_problem.json");

fn design() -> FgmDesign {
    let prob = MpqpProblem::from_json_str(PROBLEM).unwrap();
    let settings = FgmSettings {
        preconditioner: Preconditioner::Jacobi,
        momentum: Momentum::Constant,
        ..FgmSettings::default()
    };
    FgmDesign::new(BoxQp::from_mpqp(&prob).unwrap(), settings).unwrap()
}

#[test]
fn exported_static_equals_the_design_tables() {
    let d = design();
    let cert = d.certify(1e-6).unwrap();
    let data = d.data::<Q16>(&cert, None).unwrap();
    let text = export_rust("FGM", &data, ExportScalar::Q16);
    assert_eq!(
        include_str!("data/fgm_q16.rs"),
        text,
        "tests/data/fgm_q16.rs is stale: run `kestrel codegen`"
    );
    let tables = d.tables::<Q16, 2, 2, 1>(&cert, None).unwrap();
    assert_eq!(generated::FGM, tables);
    let th = [Q16::from_f64(1.5), Q16::from_f64(0.25)];
    let (mut w1, mut w2) = (FgmWorkspace::new(), FgmWorkspace::new());
    assert_eq!(
        generated::FGM.solve(&th, &mut w1).unwrap(),
        tables.solve(&th, &mut w2).unwrap()
    );
}

#[test]
fn f32_export_round_trips() {
    let d = design();
    let cert = d.certify(1e-6).unwrap();
    let data = d.data::<f32>(&cert, None).unwrap();
    let text = export_rust("FGM32", &data, ExportScalar::F32);
    // Every literal parses back to the same f32.
    let lits: Vec<f32> = text
        .split(|c: char| c == '[' || c == ']' || c == ',' || c.is_whitespace())
        .filter_map(|t| t.strip_suffix("_f32"))
        .map(|t| t.parse().unwrap())
        .collect();
    assert_eq!(lits, data.view().parts().concat());
}
