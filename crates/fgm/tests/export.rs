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
    let text = export_rust("FGM", &data, ExportScalar::Q16).unwrap();
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
    let text = export_rust("FGM32", &data, ExportScalar::F32).unwrap();
    // Every float literal (a `.` or an exponent; the counts have neither)
    // parses back to the same f32.
    let lits: Vec<f32> = text
        .split(|c: char| c == '[' || c == ']' || c == ',' || c.is_whitespace())
        .filter(|t| t.contains('.') || t.contains('e'))
        .filter_map(|t| t.parse().ok())
        .collect();
    assert_eq!(lits, data.view().parts().concat());
}

#[test]
fn a_value_the_scalar_cannot_hold_is_refused_not_written() {
    let d = design();
    let cert = d.certify(1e-6).unwrap();
    let data = d.data::<f64>(&cert, None).unwrap();
    // The f64 tables as f64 and f32 are fine; one entry beyond f32's range
    // (or Q15.16's) would be an `inf` that does not compile or a saturated
    // table: an error naming the value.
    assert!(export_rust("FGM", &data, ExportScalar::F64).is_ok());
    assert!(export_rust("FGM", &data, ExportScalar::F32).is_ok());
    let mut big = data.clone();
    big.k0[0] = 1e39;
    let e = export_rust("FGM", &big, ExportScalar::F32).unwrap_err();
    assert!(matches!(e, kestrel_fgm::FgmError::Range(_)), "{e}");
    assert!(
        e.to_string()
            .contains("1000000000000000000000000000000000000000"),
        "{e}"
    );
    assert!(export_rust("FGM", &big, ExportScalar::F64).is_ok());
    let mut wide = data.clone();
    wide.hi0[1] = 40_000.0;
    let e = export_rust("FGM", &wide, ExportScalar::Q16).unwrap_err();
    assert!(
        e.to_string().contains("40000") && e.to_string().contains("Q16"),
        "{e}"
    );
    wide.hi0[1] = f64::NAN;
    assert!(export_rust("FGM", &wide, ExportScalar::F64).is_err());
}
