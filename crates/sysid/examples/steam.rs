//! Identification of the DaISy steam generator (estimate on the first
//! half, validate on the second, order 9):
//! `cargo run --release -p kestrel-sysid --example steam [path]`.

use kestrel_sysid::{CsvColumns, IoData, N4sidSettings, Weighting, n4sid, validate};
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
    let val = val.subtract(&off)?;
    for w in [Weighting::Moesp, Weighting::Cva] {
        for h in [10usize, 15, 20] {
            let t = std::time::Instant::now();
            let r = n4sid(
                &est,
                &N4sidSettings {
                    order: Some(9),
                    weighting: w,
                    horizon: Some(h),
                    ..Default::default()
                },
            )?;
            let rep = validate(&r.model, &val, &[1, 5])?;
            println!(
                "{w:?} i={h} ({:.2}s) suggested {}",
                t.elapsed().as_secs_f64(),
                r.suggested_order
            );
            println!("{rep}");
        }
    }
    Ok(())
}
