//! Identification of the DaISy steam generator (estimate on the first
//! half, validate on the second, order 9), N4SID and PEM:
//! `cargo run --release -p kestrel-sysid --example steam [path]`.

use kestrel_sysid::{CsvColumns, IoData, N4sidSettings, PemSettings, n4sid, pem, validate};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/data/daisy/steam_generator.csv"));
    let cols = CsvColumns::new(&["u1", "u2", "u3", "u4"], &["y1", "y2", "y3", "y4"]);
    let data = IoData::read_csv(&path, &cols)?;
    let (est, val) = data.split(0.5)?;
    let (est, off) = est.remove_means()?;
    for own_means in [false, true] {
        let val = if own_means {
            val.remove_means()?.0
        } else {
            val.subtract(&off)?
        };
        for feedthrough in [false, true] {
            println!(
                "== validation means removed separately: {own_means}, feedthrough: {feedthrough}"
            );
            let t = std::time::Instant::now();
            let start = n4sid(
                &est,
                &N4sidSettings {
                    order: Some(9),
                    feedthrough,
                    ..Default::default()
                },
            )?;
            println!(
                "N4SID (MOESP, i = {}) {:.2} s",
                start.horizon,
                t.elapsed().as_secs_f64()
            );
            println!("{}", validate(&start.model, &val, &[1, 5])?);
            let t = std::time::Instant::now();
            let r = pem(
                &est,
                &start.model,
                &PemSettings {
                    feedthrough,
                    ..Default::default()
                },
            )?;
            println!(
                "PEM: {:.2} s, {} iterations, cost {:.5} -> {:.5}, stop {:?}",
                t.elapsed().as_secs_f64(),
                r.iterations,
                r.initial_cost,
                r.cost,
                r.stop
            );
            println!("{}", validate(&r.model, &val, &[1, 5])?);
        }
    }
    Ok(())
}
