//! Simulation speed of the tricopter model.
//!
//! Target (issue 3): a 250 s flight at 1 kHz integration in under 0.25 s on
//! one core. `flight 250 s coupled` is the whole closed loop (RK4 at 1 kHz,
//! gyro, gusts, pilot, rate PI, mixer, in-memory log at 50 Hz);
//! `rk4 250k steps` is the bare integrator on the same flight length.

use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_tricopter_model::{Experiment, Params, SimSettings, Tricopter, simulate};
use std::hint::black_box;

fn flight(c: &mut Criterion) {
    let mut g = c.benchmark_group("tricopter");
    g.sample_size(10);
    let settings = SimSettings::new(Experiment::Coupled, 250.0, 1);
    g.bench_function("flight 250 s coupled (1 kHz RK4, 50 Hz control)", |b| {
        b.iter(|| simulate(black_box(&settings)).unwrap().rows.len())
    });
    let model = Tricopter::new(Params::default()).unwrap();
    let trim = model.trim_hover().unwrap();
    g.bench_function("rk4 250k steps (250 s at 1 kHz, model only)", |b| {
        b.iter(|| {
            let mut x = trim.state;
            for _ in 0..250_000 {
                model.step(&mut x, black_box(&trim.input), 1e-3).unwrap();
            }
            x
        })
    });
    let log = simulate(&settings).unwrap();
    g.bench_function("csv 250 s log (12500 rows)", |b| {
        b.iter(|| log.to_csv_bytes().unwrap().len())
    });
    g.finish();
    c.bench_function("tricopter derivative", |b| {
        b.iter(|| model.derivative(black_box(&trim.state), black_box(&trim.input)))
    });
    c.bench_function("tricopter linearize", |b| {
        b.iter(|| model.linearize(black_box(&trim.state), black_box(&trim.input)))
    });
}

criterion_group!(benches, flight);
criterion_main!(benches);
