//! The firmware design: the controller tables of `avr/firmware` from design files.
//!
//! [`FirmwareDesign`] gathers everything the example firmware runs — the
//! 50 Hz design model (`kestrel.ss.v1`), the stationary Kalman filter
//! (`kestrel.kalman.v1`, kestrel-kalman), the condensed MPC problem
//! (`kestrel.mpqp.v1`, kestrel-mpc's layout `theta = [x; r; throttle]`),
//! and kestrel-fgm's preconditioned fast-gradient certificate — and
//! [`generate_tables`] writes them as the Rust source of
//! `avr/firmware/src/generated.rs` (what `kestrel export` writes).
//!
//! Conventions of the firmware's loop (see `kestrel_avr_rt::control`): the filter
//! is fed the law's output, the input *move* from the trim (`u - u0`), so
//! its tables take `u0 = 0`; the gyro bias is removed by the loop's bias
//! stage, so the measurement offset is the model's `y0` alone; the mixer
//! adds the trim (motors from the throttle, servo from 1500 us).
//!
//! ```
//! use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign, generate_tables};
//! use kestrel_core::formats::SsModel;
//! let model = SsModel::from_json_str(kestrel_tricopter::IDENTIFIED_MODEL_JSON).unwrap();
//! let design = FirmwareDesign::from_model(&model, &DesignSettings::default()).unwrap();
//! let source: String = generate_tables(&design).unwrap();
//! assert!(source.contains("pub const NX: usize = 5;"));
//! ```

pub mod c_tables;
mod consistency;
mod design;
mod empc;
mod error;
mod qp16_tables;
mod qp_tables;
mod quantize;
mod settings;
mod tables;

#[cfg(test)]
mod consistency_tests;

pub use consistency::{Consistency, ProblemCheck, ProblemFile, check_problem, estimator_model};
pub use design::{FirmwareDesign, schur_realization};
pub use empc::{empc_controller, empc_layout, empc_table_bytes, generate_empc_tables, ns2_problem};
pub use error::{DesignError, DesignPart};
pub use qp_tables::{QpTables, generate_qp_tables};
pub use qp16_tables::{
    QP16_MAX_ITERATIONS, QP16_N, QP16_P, QP16_SET_ENTRIES, QP16_SETS, generate_qp16_tables,
    qp16_tables,
};
pub use quantize::{Kalman16Design, QuantRow, quantize_row};
pub use settings::{DesignSettings, IterationBudget, NR, NU, NY, Realization, SERVO_CENTER};
pub use tables::generate_tables;
