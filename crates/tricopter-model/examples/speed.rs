//! CPU time (from /proc/self/schedstat, so independent of other load on the
//! machine) of 250 s of flight at 1 kHz: the bare RK4 and the full experiment.
use kestrel_tricopter_model::{Experiment, Params, SimSettings, Tricopter, simulate};

fn cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(0)
}

fn main() {
    let m = Tricopter::new(Params::default()).unwrap();
    let trim = m.trim_hover().unwrap();
    for _ in 0..3 {
        let mut x = trim.state;
        let c0 = cpu_ns();
        for _ in 0..250_000 {
            m.step(&mut x, std::hint::black_box(&trim.input), 1e-3)
                .unwrap();
        }
        let c1 = cpu_ns();
        let mut acc = 0.0;
        for i in 0..1_000_000 {
            x[6] = i as f64 * 1e-9;
            acc += m.derivative(std::hint::black_box(&x), &trim.input)[9];
        }
        let c2 = cpu_ns();
        let log = simulate(&SimSettings::new(Experiment::Coupled, 250.0, 1)).unwrap();
        let c3 = cpu_ns();
        println!(
            "cpu: 250k RK4 steps {:.1} ms; 1M derivatives {:.1} ms; coupled 250 s flight {:.1} ms ({} rows) {acc:e}",
            (c1 - c0) as f64 * 1e-6,
            (c2 - c1) as f64 * 1e-6,
            (c3 - c2) as f64 * 1e-6,
            log.rows.len()
        );
    }
}
