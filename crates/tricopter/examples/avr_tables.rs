//! Host-side table generator for the example firmware (design time, f64).
//!
//! ```sh
//! cargo run -p kestrel-tricopter --example avr_tables   # writes avr/firmware/src/generated.rs
//! ```
//!
//! Designs from the identified 5-state black-box model
//! `models/tricopter-blackbox-5.json` (kestrel-sysid, see models/README.md)
//! with [`kestrel_tricopter::firmware::FirmwareDesign::from_model`]: the
//! stationary Kalman filter of kestrel-kalman (kestrel-tricopter's noise design:
//! `G = [B, C']`, thesis gyro covariance (7.6) and bias (7.5)), the
//! thesis-sized MPC problem of kestrel-tricopter (N = 2, Ns = 1, 4 inputs, PWM
//! bounds around `u0`), and kestrel-fgm's preconditioned certificate for
//! the eps that keeps every input within 1 us of the optimum, folded for
//! f32 and Q16. `kestrel export --model models/tricopter-blackbox-5.json
//! --out avr/firmware/src/generated.rs` writes the same file.
//!
//! The HIL test (`tests/hil.rs`) includes this file, checks that the
//! committed `generated.rs` is what this design produces, and flies the
//! firmware against the host f64 filter and solver.

use kestrel_core::formats::SsModel;
use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign, generate_tables};
use std::path::{Path, PathBuf};

/// The design model: the identified fixture.
pub fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/tricopter-blackbox-5.json")
}

/// The firmware's design settings: the defaults (1 us input error, the
/// certified cold-start iteration count, real Schur coordinates).
pub fn settings() -> DesignSettings {
    DesignSettings::default()
}

/// Runs the design pipeline on the fixture.
pub fn design() -> FirmwareDesign {
    let model = SsModel::read(&model_path()).expect("read the design model");
    FirmwareDesign::from_model(&model, &settings()).expect("firmware design")
}

/// Path of the generated file.
pub fn generated_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../avr/firmware/src/generated.rs")
}

#[allow(dead_code)]
fn main() {
    let d = design();
    let src = generate_tables(&d).expect("tables");
    let path = generated_path();
    std::fs::write(&path, src).expect("write generated.rs");
    println!(
        "wrote {}: {} states, fgm eps {:.3e}, {} certified iterations ({:?}), condition {:.3e}, {} per period",
        path.display(),
        d.nx(),
        d.eps,
        d.cert.iterations,
        d.cert.scheme,
        d.cert.condition,
        d.loop_iterations(),
    );
}
