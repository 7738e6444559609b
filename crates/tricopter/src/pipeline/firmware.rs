//! Stage 10: tables for avr/firmware (section 7.8) of the pipeline's
//! design: the explicit law's first-move tree, the fast gradient data of
//! the thesis-sized problem, the Kalman filter of stage 4, and the
//! firmware's whole table file (`generated.rs`: the filter in Q15.16 rows,
//! the fast gradient data, the trim and the bias) of that filter and problem.

use super::config::{Config, FirmwareScalar};
use super::error::{Context, Result};
use super::explicit::Explicit;
use super::fast_gradient::FastGradient;
use super::fast_gradient::preconditioner;
use super::kalman::KalmanStage;
use super::problems::Problems;
use crate::ProblemSize;
use crate::firmware::{
    DesignSettings, FirmwareDesign, IterationBudget, Kalman16Design, Realization, generate_tables,
};
use kestrel_kalman::KalmanDesign;

/// Stage 10's result.
#[derive(Clone, Debug)]
pub struct Firmware {
    /// The tables' scalar.
    pub scalar: FirmwareScalar,
    /// Rust source of the explicit MPC's first-move search tree.
    pub empc_source: String,
    /// Bytes of those tables in f32.
    pub empc_bytes_f32: usize,
    /// Rust source of the fast gradient data.
    pub fgm_source: String,
    /// Its certified iterations.
    pub fgm_iterations: usize,
    /// The filter the firmware carries: stage 4's design.
    pub kalman: KalmanDesign,
    /// It as `kestrel.kalman.v1` (f64, the gains exactly).
    pub kalman_json: String,
    /// The firmware design of the estimator model, stage 4's filter and the
    /// thesis-sized problem (the fast gradient certified for
    /// `fgm.pwm_error`, the coordinates as identified).
    pub design: FirmwareDesign,
    /// Its filter quantised for the 16-bit Kalman kernel: each row of `C`,
    /// `M`, `A - I`, `B` with its own binary point
    /// ([`crate::firmware::quantize_row`]: `c = round(v 2^shift)`, the
    /// largest shift that keeps every `|c| <= 32767`).
    pub kalman16: Kalman16Design,
    /// The Rust source of the firmware's tables (`generated.rs`).
    pub tables_source: String,
}

/// Stage 10.
///
/// # Errors
/// A value that does not fit the chosen scalar; kestrel-fgm's errors.
pub fn run(
    cfg: &Config,
    pr: &Problems,
    kf: &KalmanStage,
    ex: &Explicit,
    fg: &FastGradient,
) -> Result<Firmware> {
    let escalar = match cfg.firmware.scalar {
        FirmwareScalar::F32 => kestrel_empc::export::ExportScalar::F32,
        FirmwareScalar::Q16 => kestrel_empc::export::ExportScalar::Q16,
    };
    let tables = &ex.thesis.first.tables;
    let empc_source = kestrel_empc::export::rust_source(tables, escalar)
        .ctx(|| "the explicit MPC's tables as Rust".into())?;
    let f = &fg.thesis;
    let (d, cert) = (&f.design, &f.pwm_certificate);
    let fgm_source = match cfg.firmware.scalar {
        FirmwareScalar::F32 => kestrel_fgm::export_rust(
            "FGM",
            &d.data::<f32>(cert, None)
                .ctx(|| "the fast gradient data in f32".into())?,
            kestrel_fgm::ExportScalar::F32,
        )
        .ctx(|| "the fast gradient tables as Rust".into())?,
        FirmwareScalar::Q16 => kestrel_fgm::export_rust(
            "FGM",
            &d.data::<kestrel_core::Q16>(cert, None)
                .ctx(|| "the fast gradient data in Q16".into())?,
            kestrel_fgm::ExportScalar::Q16,
        )
        .ctx(|| "the fast gradient tables as Rust".into())?,
    };
    let kalman = kf.design.kalman.clone();
    let design = FirmwareDesign::new(
        &pr.estimator_model,
        kalman.clone(),
        pr.thesis.mpqp.clone(),
        &DesignSettings {
            max_input_error_us: cfg.fgm.pwm_error,
            preconditioner: preconditioner(cfg.fgm.preconditioner),
            size: ProblemSize::Thesis,
            budget: IterationBudget::Certified,
            realization: Realization::AsGiven,
        },
    )
    .ctx(|| "the firmware design".into())?;
    let kalman16 = design
        .kalman16()
        .ctx(|| "the Kalman filter in Q15.16".into())?;
    let tables_source = generate_tables(&design).ctx(|| "the firmware's tables".into())?;
    Ok(Firmware {
        design,
        kalman16,
        tables_source,
        scalar: cfg.firmware.scalar,
        empc_source,
        empc_bytes_f32: tables.bytes(4),
        fgm_source,
        fgm_iterations: cert.iterations,
        kalman_json: kalman.to_json_string(),
        kalman,
    })
}
