//! The example firmware's explicit MPC (design time, f64), printed.
//!
//! ```sh
//! cargo run --release -p kestrel-tricopter --example empc_tables        # thesis-sized (N = 2, Ns = 1)
//! cargo run --release -p kestrel-tricopter --example empc_tables -- ns2 # N = 2, Ns = 2, whole box
//! ```
//!
//! Solves the MPC problem of the firmware design (the identified model in
//! real Schur coordinates, see `avr_tables`) with kestrel-empc, keeps the
//! first move, builds the search tree and prints its size. It writes
//! nothing: `kestrel codegen` writes `avr/firmware/src/generated_empc.rs`
//! (thesis-sized) and `generated_empc_ns2.rs` (Ns = 2 over half the box).

use kestrel_core::formats::SsModel;
use kestrel_tricopter::IDENTIFIED_MODEL_JSON;
use kestrel_tricopter::firmware::{
    DesignSettings, FirmwareDesign, empc_controller, generate_empc_tables, ns2_problem,
};

fn main() {
    let model = SsModel::from_json_str(IDENTIFIED_MODEL_JSON).expect("the design model");
    let d = FirmwareDesign::from_model(&model, &DesignSettings::default()).expect("design");
    let ns2 = std::env::args().nth(1).as_deref() == Some("ns2");
    let (problem, what) = if ns2 {
        (
            ns2_problem(&d.model).expect("Ns = 2 problem"),
            "N = 2, Ns = 2",
        )
    } else {
        (d.problem.clone(), "N = 2, Ns = 1")
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
    if !ns2 {
        let src = generate_empc_tables(&c, what).expect("tables");
        println!("firmware tables: {} lines of Rust", src.lines().count());
    }
}
