//! Flies one experiment and prints a summary: `cargo run --example fly -- coupled 250 1`.
use kestrel_tricopter_model::{Experiment, SimSettings, idx, simulate};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let e: Experiment = args
        .get(1)
        .map(|s| s.as_str())
        .unwrap_or("coupled")
        .parse()?;
    let secs: f64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(250.0);
    let seed: u64 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(1);
    let t0 = std::time::Instant::now();
    let log = simulate(&SimSettings::new(e, secs, seed))?;
    println!("simulated in {:?}; trim {}", t0.elapsed(), log.trim);
    println!("airborne: {:?}", log.airborne_intervals());
    let mut max = [0.0f64; 8];
    let mut sat = 0;
    for r in &log.rows {
        let x = &r.state;
        for (k, i) in [
            idx::PHI,
            idx::THETA,
            idx::P,
            idx::Q,
            idx::R,
            idx::X,
            idx::Y,
            idx::Z,
        ]
        .iter()
        .enumerate()
        {
            max[k] = max[k].max(x[*i].abs());
        }
        if r.pwm.iter().take(3).any(|p| *p >= 2000.0)
            || (r.airborne && r.pwm.iter().take(3).any(|p| *p <= 1000.0))
        {
            sat += 1;
        }
    }
    println!(
        "max |phi| {:.3} |theta| {:.3} |p| {:.3} |q| {:.3} |r| {:.3} |x| {:.2} |y| {:.2} |z| {:.2}; saturated rows {sat}",
        max[0], max[1], max[2], max[3], max[4], max[5], max[6], max[7]
    );
    for r in log.rows.iter().step_by((log.rows.len() / 25).max(1)) {
        println!(
            "t {:7.2} th {:7.1} pwm {:7.1} {:7.1} {:7.1} {:7.1} ref {:6.2} {:6.2} {:6.2} rate {:6.2} {:6.2} {:6.2} alt {:5.2} phi {:6.3}",
            r.t,
            r.throttle,
            r.pwm[0],
            r.pwm[1],
            r.pwm[2],
            r.pwm[3],
            r.reference[0],
            r.reference[1],
            r.reference[2],
            r.state[idx::P],
            r.state[idx::Q],
            r.state[idx::R],
            -r.state[idx::Z],
            r.state[idx::PHI]
        );
    }
    Ok(())
}
