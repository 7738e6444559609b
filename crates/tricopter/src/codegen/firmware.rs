//! The example firmware's tables, `avr/firmware/src/generated*.rs`, from
//! the design model `models/tricopter-blackbox-5.json`.
//!
//! The pieces are public so that the hardware-in-the-loop test builds the
//! same design and controllers once, flies them as its host reference and
//! checks (without writing) that the committed tables are theirs.

use super::file::{CodegenError, GeneratedFile, parse_input};
use crate::firmware::{
    DesignSettings, FirmwareDesign, empc_controller, generate_empc_tables, generate_qp_tables,
    generate_qp16_tables, generate_tables, ns2_problem,
};
use kestrel_avr_rt::explicit::quantize::{
    Tree16Tables, quantize_tree_layout, tree16_chunked_source,
};
use kestrel_core::formats::SsModel;
use kestrel_empc::ExplicitController;
use std::path::Path;

/// The design model, relative to the workspace root: the identified
/// 5-state black-box rate model (`kestrel.ss.v1`).
pub const MODEL: &str = "models/tricopter-blackbox-5.json";

/// The fast-gradient build's tables (Kalman filter, fast-gradient data,
/// mixer trim, gyro bias).
pub const GENERATED: &str = "avr/firmware/src/generated.rs";

/// The explicit-MPC builds' table (`N = 2, Ns = 1`).
pub const GENERATED_EMPC: &str = "avr/firmware/src/generated_empc.rs";

/// The `empc-ns2` build's table (`N = 2`, blocks `[1, 1]`, over a scaled box).
pub const GENERATED_EMPC_NS2: &str = "avr/firmware/src/generated_empc_ns2.rs";

/// The `qp` builds' table: the design's problem as a box QP (kestrel-qp).
pub const GENERATED_QP: &str = "avr/firmware/src/generated_qp.rs";

/// The `qp16` builds' table: the box QP as kestrel-avr-rt's fixed-point
/// tables (`kestrel_avr_rt::qp16`).
pub const GENERATED_QP16: &str = "avr/firmware/src/generated_qp16.rs";

/// What [`empc_file`] names the problem in the file's header.
pub const EMPC_WHAT: &str = "N = 2, Ns = 1";

/// Scale of the `empc-ns2` design's parameter box about its centre: the
/// exact first-move tree of the Ns = 2 problem over the whole box needs
/// more than the 32767 nodes of the `u16` child codes (crates/empc/README.md),
/// over half of it (states within +-5, references within +-1.5 rad/s,
/// throttle 1250-1750 us) it has about 8,000.
pub const NS2_BOX_SCALE: f64 = 0.5;

/// Largest number of own rows of the `empc-ns2` 16-bit table.
const NS2_MAX_OWN_ROWS: usize = 4096;

/// Flash chunk size (bits of the byte offset) of the `empc-ns2` table.
const NS2_CHUNK_BITS: u8 = 12;

/// The `empc-ns2` table's description in its file.
const NS2_WHAT: &str = "Explicit MPC with Ns = 2 free moves (N = 2, blocks [1, 1]) over the parameter box scaled by 0.5 about its centre (the whole box's exact tree exceeds the u16 node codes).";

/// The firmware design of the model [`MODEL`] under `root` with the
/// default settings (1 us input error, the certified cold-start iteration
/// count, real Schur coordinates): what `kestrel export --model
/// models/tricopter-blackbox-5.json` designs.
///
/// # Errors
/// [`CodegenError::Io`] / [`CodegenError::Format`] for the model file,
/// [`CodegenError::Design`] when the design refuses it.
pub fn design(root: &Path) -> Result<FirmwareDesign, CodegenError> {
    let model = parse_input(root, MODEL, SsModel::from_json_str)?;
    Ok(FirmwareDesign::from_model(
        &model,
        &DesignSettings::default(),
    )?)
}

/// [`GENERATED`]: the tables of the design `d`.
///
/// # Errors
/// [`CodegenError::Design`] from [`generate_tables`].
pub fn tables_file(d: &FirmwareDesign) -> Result<GeneratedFile, CodegenError> {
    Ok(GeneratedFile {
        path: GENERATED,
        contents: generate_tables(d)?,
        generator: "kestrel_tricopter::firmware::generate_tables of the design of models/tricopter-blackbox-5.json",
    })
}

/// [`GENERATED_QP`]: the design's problem as the box QP the `qp` builds
/// solve with kestrel-qp.
///
/// # Errors
/// [`CodegenError::Design`] from [`generate_qp_tables`].
pub fn qp_file(d: &FirmwareDesign) -> Result<GeneratedFile, CodegenError> {
    Ok(GeneratedFile {
        path: GENERATED_QP,
        contents: generate_qp_tables(d)?,
        generator: "kestrel_tricopter::firmware::generate_qp_tables of the design of models/tricopter-blackbox-5.json",
    })
}

/// [`GENERATED_QP16`]: the design's problem as the fixed-point tables the
/// `qp16` builds solve with `kestrel_avr_rt::qp16`.
///
/// # Errors
/// [`CodegenError::Design`] from [`generate_qp16_tables`].
pub fn qp16_file(d: &FirmwareDesign) -> Result<GeneratedFile, CodegenError> {
    Ok(GeneratedFile {
        path: GENERATED_QP16,
        contents: generate_qp16_tables(d)?,
        generator: "kestrel_tricopter::firmware::generate_qp16_tables of the design of models/tricopter-blackbox-5.json",
    })
}

/// The explicit controller of the design's own problem (`N = 2, Ns = 1`).
///
/// # Errors
/// [`CodegenError::Design`] from [`empc_controller`].
pub fn empc(d: &FirmwareDesign) -> Result<ExplicitController, CodegenError> {
    Ok(empc_controller(&d.problem)?)
}

/// [`GENERATED_EMPC`]: the tables of the explicit controller `c` of the
/// design's problem ([`empc`]).
///
/// # Errors
/// [`CodegenError::Design`] from [`generate_empc_tables`].
pub fn empc_file(c: &ExplicitController) -> Result<GeneratedFile, CodegenError> {
    Ok(GeneratedFile {
        path: GENERATED_EMPC,
        contents: generate_empc_tables(c, EMPC_WHAT)?,
        generator: "kestrel_tricopter::firmware::generate_empc_tables of the explicit controller of the design's problem",
    })
}

/// The explicit controller with `Ns = 2` free moves (`N = 2`, blocks
/// `[1, 1]`, [`ns2_problem`] of the design's model) over the parameter box
/// scaled by [`NS2_BOX_SCALE`].
///
/// # Errors
/// [`CodegenError::Design`] from [`ns2_problem`] and [`empc_controller`].
pub fn ns2_empc(d: &FirmwareDesign) -> Result<ExplicitController, CodegenError> {
    let mut problem = ns2_problem(&d.model)?;
    problem.scale_parameter_box(NS2_BOX_SCALE);
    Ok(empc_controller(&problem)?)
}

/// The `empc-ns2` build's 16-bit table of [`ns2_empc`]'s controller, in
/// the wide layout.
///
/// # Errors
/// [`CodegenError::Quantize`] when the tree has no 16-bit table.
pub fn ns2_tables(c: &ExplicitController) -> Result<Tree16Tables, CodegenError> {
    Ok(quantize_tree_layout(&c.tables, NS2_MAX_OWN_ROWS, true)?)
}

/// [`GENERATED_EMPC_NS2`]: [`ns2_tables`] of `c` (from [`ns2_empc`]) in
/// flash chunks.
///
/// # Errors
/// [`CodegenError::Quantize`] as [`ns2_tables`].
pub fn empc_ns2_file(c: &ExplicitController) -> Result<GeneratedFile, CodegenError> {
    let q = ns2_tables(c)?;
    Ok(GeneratedFile {
        path: GENERATED_EMPC_NS2,
        contents: tree16_chunked_source(&q, "EMPC_NS2", NS2_CHUNK_BITS, NS2_WHAT)?,
        generator: "kestrel_avr_rt::explicit::quantize::tree16_chunked_source of the Ns = 2 explicit controller of the design's model",
    })
}

/// The five firmware tables of the design model under `root`.
///
/// # Errors
/// As [`design`], [`tables_file`], [`qp_file`], [`qp16_file`],
/// [`empc_file`] and [`empc_ns2_file`].
pub fn files(root: &Path) -> Result<Vec<GeneratedFile>, CodegenError> {
    let d = design(root)?;
    Ok(vec![
        tables_file(&d)?,
        qp_file(&d)?,
        qp16_file(&d)?,
        empc_file(&empc(&d)?)?,
        empc_ns2_file(&ns2_empc(&d)?)?,
    ])
}
