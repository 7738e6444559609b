//! Stage 10: tables for avr/firmware (section 7.8) of the pipeline's
//! design: the explicit law's first-move tree, the fast gradient data of
//! the thesis-sized problem, and the Kalman filter of stage 4.

use super::config::{Config, FirmwareScalar};
use super::error::{Context, Result};
use super::explicit::Explicit;
use super::fast_gradient::FastGradient;
use super::kalman::KalmanStage;
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
}

/// Stage 10.
///
/// # Errors
/// A value that does not fit the chosen scalar; kestrel-fgm's errors.
pub fn run(cfg: &Config, kf: &KalmanStage, ex: &Explicit, fg: &FastGradient) -> Result<Firmware> {
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
        ),
        FirmwareScalar::Q16 => kestrel_fgm::export_rust(
            "FGM",
            &d.data::<kestrel_core::Q16>(cert, None)
                .ctx(|| "the fast gradient data in Q16".into())?,
            kestrel_fgm::ExportScalar::Q16,
        ),
    };
    let kalman = kf.design.kalman.clone();
    Ok(Firmware {
        scalar: cfg.firmware.scalar,
        empc_source,
        empc_bytes_f32: tables.bytes(4),
        fgm_source,
        fgm_iterations: cert.iterations,
        kalman_json: kalman.to_json_string(),
        kalman,
    })
}
