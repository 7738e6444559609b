//! The example firmware's design (design time, f64), printed.
//!
//! ```sh
//! cargo run -p kestrel-tricopter --example avr_tables
//! ```
//!
//! Designs from the identified 5-state black-box model (this crate's copy
//! of `models/tricopter-blackbox-5.json`) with
//! [`kestrel_tricopter::firmware::FirmwareDesign::from_model`]: the
//! stationary Kalman filter of kestrel-kalman (kestrel-tricopter's noise
//! design: `G = [B, C']`, thesis gyro covariance (7.6) and bias (7.5)), the
//! thesis-sized MPC problem (N = 2, Ns = 1, 4 inputs, PWM bounds around
//! `u0`), and kestrel-fgm's preconditioned certificate for the eps that
//! keeps every input within 1 us of the optimum, folded for f32 and Q16;
//! prints the design and the size of its tables. It writes nothing:
//! `kestrel codegen` writes `avr/firmware/src/generated.rs` from the same
//! design (`kestrel export --model models/tricopter-blackbox-5.json` prints
//! it).

use kestrel_core::formats::SsModel;
use kestrel_tricopter::IDENTIFIED_MODEL_JSON;
use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign, generate_tables};

fn main() {
    let model = SsModel::from_json_str(IDENTIFIED_MODEL_JSON).expect("the design model");
    let d = FirmwareDesign::from_model(&model, &DesignSettings::default()).expect("design");
    let src = generate_tables(&d).expect("tables");
    println!(
        "{} states, fgm eps {:.3e}, {} certified iterations ({:?}), condition {:.3e}, {} per period; tables: {} lines of Rust",
        d.nx(),
        d.eps,
        d.cert.iterations,
        d.cert.scheme,
        d.cert.condition,
        d.loop_iterations(),
        src.lines().count(),
    );
}
