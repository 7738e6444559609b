//! The DaISy steam generator with ONE model for all three targets: the
//! dynamics `A, B, C` from a multi-step-focus PEM fit (the `1..=h`-step
//! predictions together), then only the noise model `K` re-estimated with
//! the dynamics fixed, by the `1..=hk`-step criterion
//! ([`PemFocus::MultiStepThenNoise`](kestrel_sysid::workflow::PemFocus)).
//!
//! `h`, `hk` and whether to estimate a feed-through `D` are chosen by
//! cross-validation inside the estimation half (fit on its first 2/3,
//! score on its last 1/3; score: the sum of the mean simulation, 1-step
//! and 5-step fits; the two `D` choices run on two threads). The chosen configuration is
//! then fitted on the whole estimation half and validated once on the
//! second half: `cargo run --release -p kestrel-sysid --example steam_focus [path]`.

#[path = "common/steam.rs"]
mod steam;

use kestrel_sysid::{InnovationModel, IoData, PemSettings};
use steam::{dynamics, fits, table, timed_pem};

/// Dynamics horizons and noise-model horizons tried.
const DYNAMICS_HORIZONS: [usize; 4] = [6, 8, 10, 12];
const NOISE_HORIZONS: [usize; 3] = [1, 3, 5];

/// Multi-step dynamics (`h`), then `K` for each noise horizon; returns the
/// models `(hk, model)`, the first with `hk = 0` meaning "K of the
/// multi-step fit kept".
fn fit(
    est: &IoData,
    h: usize,
    feedthrough: bool,
    noise_horizons: &[usize],
) -> Result<Vec<(usize, InnovationModel)>, String> {
    let dynamics = dynamics(
        est,
        Default::default(),
        &PemSettings {
            horizon: h,
            feedthrough,
            ..Default::default()
        },
        &format!("  h = {h}, D {feedthrough}"),
    )?;
    let mut out = vec![(0, dynamics.model.clone())];
    for &hk in noise_horizons {
        let k = timed_pem(
            est,
            &dynamics.model,
            &PemSettings {
                fixed_dynamics: true,
                horizon: hk,
                ..Default::default()
            },
            &format!("    K by 1..{hk}"),
        )?;
        out.push((hk, k.model));
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Cross-validation inside the estimation half only.
    let steam::Split {
        est,
        val,
        inner_est,
        inner_val,
    } = steam::split()?;
    println!("cross-validation inside the estimation half (fit on 2/3, score on 1/3):");
    println!(
        "| D | h | K by | simulation | 1-step | 5-step | score |\n|---|---|---|---|---|---|---|"
    );
    let grid = |feedthrough: bool| -> Result<Vec<_>, String> {
        let mut out = Vec::new();
        for h in DYNAMICS_HORIZONS {
            for (hk, model) in fit(&inner_est, h, feedthrough, &NOISE_HORIZONS)? {
                out.push((feedthrough, h, hk, model));
            }
        }
        Ok(out)
    };
    let (without, with) = std::thread::scope(|s| {
        let a = s.spawn(|| grid(false));
        let b = s.spawn(|| grid(true));
        (a.join(), b.join())
    });
    let mut models = without.map_err(|_| "thread panicked")??;
    models.extend(with.map_err(|_| "thread panicked")??);
    let mut best: Option<(f64, bool, usize, usize)> = None;
    for (feedthrough, h, hk, model) in models {
        {
            let f = fits(&model, &inner_val)?;
            let score = f.score();
            let by = if hk == 0 {
                format!("1..{h} (kept)")
            } else {
                format!("1..{hk}")
            };
            let d = if feedthrough { "yes" } else { "no" };
            println!(
                "| {d} | {h} | {by} | {:.2} | {:.2} | {:.2} | {score:.2} |",
                f.sim, f.one, f.five
            );
            if hk > 0 && best.is_none_or(|(s, ..)| score > s) {
                best = Some((score, feedthrough, h, hk));
            }
        }
    }
    let (_, feedthrough, h, hk) = best.ok_or("no configuration")?;
    println!(
        "chosen by the inner score: dynamics 1..{h}, K by 1..{hk}, D estimated: {feedthrough}"
    );

    // The chosen configuration on the whole estimation half, validated once.
    let t = std::time::Instant::now();
    let models = fit(&est, h, feedthrough, &[hk])?;
    let (_, model) = models.last().ok_or("no model")?;
    table(
        &format!(
            "PEM, multi-step focus 1..{h} (D estimated: {feedthrough}) then K by 1..{hk} ({:.1} s)",
            t.elapsed().as_secs_f64()
        ),
        model,
        &val,
    )?;
    Ok(())
}
