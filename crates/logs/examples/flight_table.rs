//! The table of docs/logs.md: what each real log of `../shared/data/flight`
//! yields with the default signals and segments, at 50 Hz and 500 Hz.
//!
//! `cargo run -p kestrel-logs --example flight_table`

use kestrel_logs::{ImportSettings, import, read_file};
use std::path::PathBuf;

fn main() -> Result<(), kestrel_logs::LogError> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/flight");
    println!(
        "| log | samples | native rate | span (s) | airborne segments (s) | rows at 50 Hz | rows at 500 Hz (interpolated cells) | read |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for file in [
        "betaflight/btfl_002.bbl",
        "crazyflie/log10",
        "crazyflie/log15",
        "crazyflie/log16",
    ] {
        let start = std::time::Instant::now();
        let logs = read_file(&root.join(file), &Default::default())?;
        let read = start.elapsed();
        let at = |rate_hz| {
            import(
                &logs,
                &ImportSettings {
                    rate_hz,
                    ..Default::default()
                },
            )
        };
        let (slow, fast) = (at(50.0)?, at(500.0)?);
        for (k, l) in slow.logs.iter().enumerate() {
            let segs: Vec<String> = l
                .segments
                .iter()
                .map(|s| format!("{:.2}-{:.2} ({:.1})", s.start, s.end, s.end - s.start))
                .collect();
            let rows = |imp: &kestrel_logs::Imported| -> (usize, usize) {
                let e = imp.experiments.iter().filter(|e| e.log == k);
                e.fold((0, 0), |(n, f), e| (n + e.t.len(), f + e.filled))
            };
            let ((n50, _), (n500, f500)) = (rows(&slow), rows(&fast));
            println!(
                "| {file}{} | {} | {:.1} Hz | {:.2}-{:.2} | {} | {n50} | {n500} ({f500}) | {:.0} ms |",
                if slow.logs.len() > 1 {
                    format!(" log {}", k + 1)
                } else {
                    String::new()
                },
                l.samples,
                l.native_rate_hz,
                l.span.start,
                l.span.end,
                segs.join(", "),
                read.as_secs_f64() * 1e3,
            );
        }
    }
    Ok(())
}
