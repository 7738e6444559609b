//! Simulation speed of the tricopter model.
//!
//! Target (issue 3): a 250 s flight at 1 kHz integration in under 0.25 s on
//! one core. `flight 250 s coupled` is the whole closed loop (RK4 at 1 kHz,
//! gyro, gusts, pilot, rate PI, mixer, in-memory log at 50 Hz);
//! `rk4 250k steps` is the bare integrator on the same flight length.
//!
//! Each is measured twice: in wall-clock time (criterion's default) and in
//! CPU time of the benchmark thread (`/proc/thread-self/schedstat`, Linux),
//! which is what "on one core" means and is not inflated when other
//! processes share the cores. Elsewhere the CPU-time group reads 0 and is
//! skipped.

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kestrel_tricopter_model::{Experiment, Params, SimSettings, Tricopter, simulate};
use std::hint::black_box;

/// CPU time of the current thread in nanoseconds (0 where unavailable).
fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(0)
}

/// Criterion measurement: CPU time of the benchmark thread.
struct ThreadCpuTime;

struct NsFormatter;

impl ValueFormatter for NsFormatter {
    fn scale_values(&self, ns: f64, values: &mut [f64]) -> &'static str {
        let (factor, unit) = if ns < 1e3 {
            (1.0, "ns (cpu)")
        } else if ns < 1e6 {
            (1e-3, "µs (cpu)")
        } else if ns < 1e9 {
            (1e-6, "ms (cpu)")
        } else {
            (1e-9, "s (cpu)")
        };
        for v in values {
            *v *= factor;
        }
        unit
    }
    fn scale_throughputs(
        &self,
        _typical: f64,
        _t: &Throughput,
        _values: &mut [f64],
    ) -> &'static str {
        "ns (cpu)"
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}

impl Measurement for ThreadCpuTime {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, i: u64) -> u64 {
        thread_cpu_ns().saturating_sub(i)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &NsFormatter
    }
}

fn flight_benches<M: Measurement>(c: &mut Criterion<M>, group: &str) {
    let mut g = c.benchmark_group(group);
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
}

fn wall(c: &mut Criterion) {
    flight_benches(c, "tricopter");
    let model = Tricopter::new(Params::default()).unwrap();
    let trim = model.trim_hover().unwrap();
    c.bench_function("tricopter derivative", |b| {
        b.iter(|| model.derivative(black_box(&trim.state), black_box(&trim.input)))
    });
    c.bench_function("tricopter linearize", |b| {
        b.iter(|| model.linearize(black_box(&trim.state), black_box(&trim.input)))
    });
    c.bench_function("tricopter trim_hover", |b| {
        b.iter(|| black_box(&model).trim_hover().unwrap())
    });
}

fn cpu(c: &mut Criterion<ThreadCpuTime>) {
    if thread_cpu_ns() == 0 {
        return;
    }
    flight_benches(c, "tricopter-cpu");
}

criterion_group!(wall_group, wall);
criterion_group! {
    name = cpu_group;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = cpu
}
criterion_main!(wall_group, cpu_group);
