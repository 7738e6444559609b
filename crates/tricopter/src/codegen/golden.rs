//! The libraries' golden files (the exported tables their tests include
//! and compare) and the fixtures derived from the design model.
//!
//! Each is produced by the library's own export function from the input
//! its test reads, so a test that recomputes the file and compares fails
//! exactly when `kestrel codegen --check` does.

use super::file::{CodegenError, GeneratedFile, parse_input, read_input};
use super::firmware::MODEL;
use crate::firmware::ns2_problem;
use crate::{ProblemSize, default_weights, tricopter_problem};
use kestrel_core::Q16;
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_empc::export::{ExportScalar, rust_source};
use kestrel_empc::locate::{LocateSettings, build_lists};
use kestrel_empc::{EmpcError, Settings, TreeSettings, build_compact, build_controller, solve};
use kestrel_fgm::{BoxQp, FgmDesign, FgmSettings, Momentum, Preconditioner, export_rust};
use std::path::Path;

/// kestrel-empc's golden problem (`kestrel.mpqp.v1`, two parameters).
pub const EMPC_BOX2: &str = "crates/empc/tests/generated/box2.json";

/// kestrel-fgm's golden problem (`kestrel.mpqp.v1`).
pub const FGM_PROBLEM: &str = "crates/fgm/tests/data/fgm_problem.json";

/// kestrel-fgm's golden table: [`FGM_PROBLEM`] certified and exported in Q16.
pub const FGM_Q16: &str = "crates/fgm/tests/data/fgm_q16.rs";

/// The `Ns = 2` thesis problem as a kestrel-empc fixture.
pub const THESIS_NS2: &str = "crates/empc/tests/data/thesis-ns2.json";

/// The thesis-sized tricopter problem (`kestrel mpc --tricopter --horizon 2
/// --blocks 2`, default weights) for kestrel-avr-rt's `qp16` tests.
pub const QP16_THESIS: &str = "crates/avr-rt/tests/data/qp16-thesis.mpqp.json";
/// The larger problem (N = 10, blocks [1, 1, 2, 6]) for kestrel-avr-rt's
/// `qp16` tests (kestrel-avr-rt cannot depend on this crate).
pub const QP16_LARGER: &str = "crates/avr-rt/tests/data/qp16-larger.mpqp.json";
/// This crate's embedded copy of [`MODEL`] (`identified_model`).
pub const MODEL_COPY: &str = "crates/tricopter/data/tricopter-blackbox-5.json";

/// The input accuracy kestrel-fgm's golden table is certified for.
pub const FGM_EPS: f64 = 1e-6;

/// kestrel-empc's golden tables of [`EMPC_BOX2`]: the exact solution's
/// search tree in the narrow (`f32`, `q16`), wide (`f32`, `f64`) and
/// compact (`f32`, `f64`, `q16`) layouts, as `cargo test -p kestrel-empc
/// --test export --test wide` includes and compares them, and its
/// candidate lists (`leaf_regions` 1, narrow, `f32`) that `cargo test -p
/// kestrel-empc --test locate_source` includes and compares.
///
/// # Errors
/// [`CodegenError::Io`] or [`CodegenError::Format`] for the problem
/// file; [`CodegenError::Empc`] from kestrel-empc.
pub fn empc_files(root: &Path) -> Result<Vec<GeneratedFile>, CodegenError> {
    const GEN: &str = "kestrel_empc::export of the tree of crates/empc/tests/generated/box2.json";
    let prob = parse_input(root, EMPC_BOX2, MpqpProblem::from_json_str)?;
    let sol = solve(&prob, &Settings::default())?;
    let ctl = build_controller(&prob, &sol, &TreeSettings::default())?;
    let compact = build_compact(&prob, &sol, &TreeSettings::default())?;
    let wide = ctl.tables.widen();
    let lists = build_lists(
        &prob,
        &sol,
        &LocateSettings {
            leaf_regions: 1,
            ..LocateSettings::default()
        },
        &mut |_| {},
    )?;
    let lists = lists
        .tables
        .narrow()
        .ok_or_else(|| {
            EmpcError::InvalidArgument(format!(
                "{EMPC_BOX2}'s candidate lists do not fit the narrow (u16) tables"
            ))
        })?
        .rust_source(ExportScalar::F32)?;
    let file = |path, contents| GeneratedFile {
        path,
        contents,
        generator: GEN,
    };
    Ok(vec![
        file(
            "crates/empc/tests/generated/box2_f32.rs",
            rust_source(&ctl.tables, ExportScalar::F32)?,
        ),
        file(
            "crates/empc/tests/generated/box2_q16.rs",
            rust_source(&ctl.tables, ExportScalar::Q16)?,
        ),
        file(
            "crates/empc/tests/generated/box2_wide_f32.rs",
            rust_source(&wide, ExportScalar::F32)?,
        ),
        file(
            "crates/empc/tests/generated/box2_wide_f64.rs",
            rust_source(&wide, ExportScalar::F64)?,
        ),
        file(
            "crates/empc/tests/generated/box2_compact_f32.rs",
            rust_source(&compact.tables, ExportScalar::F32)?,
        ),
        file(
            "crates/empc/tests/generated/box2_compact_f64.rs",
            rust_source(&compact.tables, ExportScalar::F64)?,
        ),
        file(
            "crates/empc/tests/generated/box2_compact_q16.rs",
            rust_source(&compact.tables, ExportScalar::Q16)?,
        ),
        file("crates/empc/tests/generated/box2_lists_f32.rs", lists),
    ])
}

/// kestrel-fgm's golden table [`FGM_Q16`]: [`FGM_PROBLEM`] with the Jacobi
/// preconditioner and constant momentum, certified for [`FGM_EPS`],
/// exported as the Q16 static `FGM` (what `cargo test -p kestrel-fgm
/// --test export` includes and compares).
///
/// # Errors
/// [`CodegenError::Io`] or [`CodegenError::Format`] for the problem
/// file; [`CodegenError::Fgm`] from kestrel-fgm.
pub fn fgm_file(root: &Path) -> Result<GeneratedFile, CodegenError> {
    let prob = parse_input(root, FGM_PROBLEM, MpqpProblem::from_json_str)?;
    let settings = FgmSettings {
        preconditioner: Preconditioner::Jacobi,
        momentum: Momentum::Constant,
        ..FgmSettings::default()
    };
    let design = FgmDesign::new(BoxQp::from_mpqp(&prob)?, settings)?;
    let cert = design.certify(FGM_EPS)?;
    let data = design.data::<Q16>(&cert, None)?;
    Ok(GeneratedFile {
        path: FGM_Q16,
        contents: export_rust("FGM", &data, kestrel_fgm::ExportScalar::Q16)?,
        generator: "kestrel_fgm::export_rust of the certified design of crates/fgm/tests/data/fgm_problem.json",
    })
}

/// The fixtures derived from the design model [`MODEL`]: kestrel-empc's
/// [`THESIS_NS2`] (the `Ns = 2` problem of the model as given, checked by
/// `cargo test -p kestrel-tests --test empc_ns2`), kestrel-avr-rt's
/// [`QP16_THESIS`] and [`QP16_LARGER`] (the tricopter problems of its `qp16`
/// tests, with the model's fingerprint) and this crate's
/// embedded copy [`MODEL_COPY`].
///
/// # Errors
/// [`CodegenError::Io`] or [`CodegenError::Format`] for the model
/// file; [`CodegenError::Design`] from [`ns2_problem`];
/// [`CodegenError::Problem`] from [`tricopter_problem`].
pub fn model_files(root: &Path) -> Result<Vec<GeneratedFile>, CodegenError> {
    let text = read_input(root, MODEL)?;
    let model = parse_input(root, MODEL, SsModel::from_json_str)?;
    Ok(vec![
        GeneratedFile {
            path: THESIS_NS2,
            contents: ns2_problem(&model)?.to_json_string(),
            generator: "kestrel_tricopter::firmware::ns2_problem of models/tricopter-blackbox-5.json",
        },
        GeneratedFile {
            path: QP16_THESIS,
            contents: qp16_problem(&model, ProblemSize::Thesis)?,
            generator: "kestrel_tricopter::tricopter_problem (thesis-sized, default weights) of models/tricopter-blackbox-5.json",
        },
        GeneratedFile {
            path: QP16_LARGER,
            contents: qp16_problem(&model, ProblemSize::Larger)?,
            generator: "kestrel_tricopter::tricopter_problem (larger, default weights) of models/tricopter-blackbox-5.json",
        },
        GeneratedFile {
            path: MODEL_COPY,
            contents: text,
            generator: "a copy of models/tricopter-blackbox-5.json",
        },
    ])
}

/// The tricopter problem of `size` with the default weights, as the
/// `kestrel.mpqp.v1` text `kestrel mpc --tricopter` writes.
fn qp16_problem(model: &SsModel, size: ProblemSize) -> Result<String, CodegenError> {
    let (q1, q2) = default_weights();
    Ok(tricopter_problem(model, size, q1, q2)?
        .to_mpqp()
        .to_json_string_for_model(model))
}
