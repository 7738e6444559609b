//! Host-side explicit-MPC table generator for the example firmware.
//!
//! ```sh
//! cargo run --release -p kestrel-tricopter --example empc_tables        # thesis-sized (N = 2, Ns = 1)
//! cargo run --release -p kestrel-tricopter --example empc_tables -- ns2 # N = 2, Ns = 2 (report only)
//! ```
//!
//! Solves the MPC problem of the firmware design (the identified model in
//! real Schur coordinates, see `avr_tables`) with kestrel-empc, keeps the
//! first move, builds the search tree, and writes
//! `avr/firmware/src/generated_empc.rs` (thesis-sized) or prints the Ns = 2
//! tree's size.

use kestrel_core::formats::SsModel;
use kestrel_tricopter::firmware::{
    DesignSettings, FirmwareDesign, empc_controller, generate_empc_tables, ns2_problem,
};
use std::path::Path;

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let model = SsModel::read(&root.join("models/tricopter-blackbox-5.json")).expect("model");
    let d = FirmwareDesign::from_model(&model, &DesignSettings::default()).expect("design");
    let ns2 = std::env::args().nth(1).as_deref() == Some("ns2");
    let (problem, what, file) = if ns2 {
        (
            ns2_problem(&d.model).expect("Ns = 2 problem"),
            "N = 2, Ns = 2",
            "generated_empc_ns2.rs",
        )
    } else {
        (d.problem.clone(), "N = 2, Ns = 1", "generated_empc.rs")
    };
    let t = std::time::Instant::now();
    let c = empc_controller(&problem).expect("explicit controller");
    println!(
        "{what}: {} variables, {} parameters: {:?}; {} bytes (4-byte numbers); {:.1} s",
        problem.n(),
        problem.p(),
        c.stats,
        c.tables.bytes(4),
        t.elapsed().as_secs_f64()
    );
    let src = generate_empc_tables(&c, what).expect("tables");
    let path = root.join("avr/firmware/src").join(file);
    std::fs::write(&path, src).expect("write");
    println!("wrote {}", path.display());
}
