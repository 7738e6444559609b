//! The DaISy steam generator's subspace models alone: N4SID of order 9
//! for every weighting (MOESP, CVA, unweighted), block rows `i` in
//! `STEAM_HORIZONS` (default `5,8,10,15,20`) and both ways of estimating
//! the matrices ([`MatrixEstimate::OutputError`], the default, and
//! [`MatrixEstimate::StateRegression`]), without feed-through. Each row
//! gives the mean simulation, 1-step and 5-step fits on the inner split
//! of the estimation half (fit on its first 2/3, scored on its last 1/3)
//! and on the validation half, for comparison only (no choice is made):
//!
//! `cargo run --release -p kestrel-sysid --example steam_subspace [path]`
//! (about 25 s).

#[path = "common/steam.rs"]
mod steam;

use kestrel_sysid::{MatrixEstimate, N4sidSettings, Weighting, n4sid};
use steam::{Fits, ORDER, fits, list, split};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let horizons = list("STEAM_HORIZONS", "5,8,10,15,20", |s| {
        s.parse::<usize>().ok()
    })?;
    let s = split()?;
    let cell = |f: &Fits| format!("{:.2} | {:.2} | {:.2}", f.sim, f.one, f.five);
    println!(
        "| weighting | matrices | i | inner simulation | inner 1-step | inner 5-step | simulation | 1-step | 5-step |\n|---|---|---|---|---|---|---|---|---|"
    );
    for weighting in [Weighting::Moesp, Weighting::Cva, Weighting::Unweighted] {
        for matrices in [MatrixEstimate::OutputError, MatrixEstimate::StateRegression] {
            for &i in &horizons {
                let settings = N4sidSettings {
                    order: Some(ORDER),
                    horizon: Some(i),
                    weighting,
                    matrices,
                    ..Default::default()
                };
                let inner = n4sid(&s.inner_est, &settings)
                    .map_err(|e| e.to_string())
                    .and_then(|r| fits(&r.model, &s.inner_val));
                let full = n4sid(&s.est, &settings)
                    .map_err(|e| e.to_string())
                    .and_then(|r| fits(&r.model, &s.val));
                match (inner, full) {
                    (Ok(a), Ok(b)) => println!(
                        "| {weighting:?} | {matrices:?} | {i} | {} | {} |",
                        cell(&a),
                        cell(&b)
                    ),
                    (a, b) => println!(
                        "| {weighting:?} | {matrices:?} | {i} | {:?} | {:?} |",
                        a.err(),
                        b.err()
                    ),
                }
            }
        }
    }
    Ok(())
}
