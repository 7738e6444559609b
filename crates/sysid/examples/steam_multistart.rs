//! Is the optimiser the limit on the DaISy steam generator? The
//! criterion of the `steam_regression` choice (PEM, fit criterion over
//! the prediction steps `STEAM_STEPS`, default `1+5`, `D` and `K`
//! estimated, to convergence) fitted on the estimation half from many
//! state-regression N4SID starts of order 9: every weighting (MOESP, CVA,
//! unweighted) with block rows `i` in `STEAM_HORIZONS` (default
//! `4,5,6,8,10,12,15`). The searches are sorted by their in-sample
//! criterion (the sum of the mean 1-step and 5-step fits on the
//! estimation half: the fit criterion's measure for the default steps),
//! and the best optimum of the criterion is validated once on the second
//! half. The validation half is also scored with its own means removed
//! and with its own straight lines removed, to show how much the
//! offset protocol matters. `STEAM_SHOW_ALL=1` validates every search
//! (exploration, not a choice); `STEAM_ORDER` (default 9, the issue's
//! order) sets the model order, to see what one more state buys:
//!
//! `cargo run --release -p kestrel-sysid --example steam_multistart [path]`
//! (about 6 minutes on 2 cores).

#[path = "common/steam.rs"]
mod steam;

use kestrel_sysid::{Criterion, PemSettings, Weighting, pem};
use steam::{Fits, ORDER, fits, in_threads, list, table};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let horizons = list("STEAM_HORIZONS", "4,5,6,8,10,12,15", |s| {
        s.parse::<usize>().ok()
    })?;
    let steps = list("STEAM_STEPS", "1+5", steam::step_list)?
        .into_iter()
        .next()
        .ok_or("STEAM_STEPS: no step list")?;
    let threads = steam::env_number("STEAM_THREADS", 2).max(1);
    let show_all = std::env::var("STEAM_SHOW_ALL").is_ok_and(|v| v == "1");
    let order = steam::env_number("STEAM_ORDER", ORDER);
    let steam::Halves { est, val } = steam::halves()?;
    let settings = PemSettings {
        criterion: Criterion::Fit,
        horizon: steps.iter().copied().max().unwrap_or(1),
        steps: steps.clone(),
        feedthrough: true,
        max_iterations: steam::env_number("STEAM_MAX_ITER", 200),
        ..Default::default()
    };
    let starts: Vec<(Weighting, usize)> = [Weighting::Moesp, Weighting::Cva, Weighting::Unweighted]
        .into_iter()
        .flat_map(|w| horizons.iter().map(move |&i| (w, i)))
        .collect();
    let t = std::time::Instant::now();
    let mut done = in_threads(
        &starts,
        threads,
        |(w, i)| format!("{w:?} i = {i}"),
        |&(weighting, i)| {
            let start = steam::regression_start(&est, order, weighting, i)?;
            let r = pem(&est, &start, &settings).map_err(|e| e.to_string())?;
            let inside = fits(&r.model, &est)?;
            eprintln!(
                "{weighting:?} i = {i}: {} iterations, stop {:?}",
                r.iterations, r.stop
            );
            Ok((weighting, i, inside, r))
        },
    )?;
    let criterion = |f: &Fits| f.one + f.five;
    done.sort_by(|a, b| criterion(&b.2).total_cmp(&criterion(&a.2)));
    println!(
        "order {order}: {} searches from {} starts ({:.0} s), best in-sample criterion first:",
        done.len(),
        starts.len(),
        t.elapsed().as_secs_f64()
    );
    println!(
        "| start | iterations | in-sample 1-step + 5-step | in-sample simulation | validation (simulation / 1-step / 5-step) |\n|---|---|---|---|---|"
    );
    for (w, i, inside, r) in &done {
        let shown = if show_all {
            let f = fits(&r.model, &val)?;
            format!("{:.2} / {:.2} / {:.2}", f.sim, f.one, f.five)
        } else {
            "-".into()
        };
        println!(
            "| {w:?} i = {i} | {} | {:.3} | {:.2} | {shown} |",
            r.iterations,
            criterion(inside),
            inside.sim
        );
    }
    let (w, i, _, best) = done.first().ok_or("no search succeeded")?;
    table(
        &format!("order {order}, the best optimum of the criterion ({w:?} i = {i})"),
        &best.model,
        &val,
    )?;
    // The same model on the validation half with its own offsets (a
    // constant shift does not change them, so `val` serves).
    for (label, data) in [
        ("its own means removed", val.remove_means()?.0),
        ("its own straight lines removed", val.detrend()),
    ] {
        let f = fits(&best.model, &data)?;
        println!(
            "validation half with {label}: {:.2} / {:.2} / {:.2}",
            f.sim, f.one, f.five
        );
    }
    Ok(())
}
