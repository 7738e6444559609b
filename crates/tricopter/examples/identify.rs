//! Section 7.4 of the thesis on the simulated tricopter: the black-box and
//! black-box virtual models (order 8 by PEM, reduced to 5 by `balred`)
//! from flights no. 2 and 3, with the fit, 5-step and residual tables, and
//! the plain prediction-focus PEM beside them.
//!
//! `cargo run --release -p kestrel-tricopter --example identify [seconds] [seed]`

use kestrel_sysid::workflow::{Segment, identify};
use kestrel_tricopter::ident::{ModelKind, prediction_spec, simulated_flights, thesis_spec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seconds = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(250.0);
    let seed = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(1);
    let flights = simulated_flights(seconds, seed)?;
    for (title, kind) in [
        ("black-box", ModelKind::BlackBox),
        ("black-box virtual", ModelKind::Virtual),
    ] {
        let r = identify(&flights, &thesis_spec(kind))?;
        println!("=== {title} model (focus simulation-then-noise)\n{r}");
        if let Some(full) = &r.full_validation {
            println!("order {} before balred:\n{full}", r.full_model.nx());
        }
        let p = identify(&flights, &prediction_spec(kind))?;
        println!(
            "--- {title}, prediction focus for comparison:\n{}",
            p.validation
        );
    }
    let mut thesis_virtual = thesis_spec(ModelKind::Virtual);
    thesis_virtual.estimate =
        Segment::parse_list(kestrel_tricopter::ident::VIRTUAL_ESTIMATE_THESIS)?;
    thesis_virtual.validate =
        Segment::parse_list(kestrel_tricopter::ident::VIRTUAL_VALIDATE_THESIS)?;
    let r = identify(&flights, &thesis_virtual)?;
    println!(
        "--- black-box virtual on the thesis's flight-2-only sets:\n{}",
        r.validation
    );
    Ok(())
}
