//! Benchmarks of kestrel-sysid: PEM on 5,000 samples of a random stable
//! 8th-order, 4-input, 3-output innovation model (started from N4SID, the
//! issue's target is under 2 s), and N4SID alone.

use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_sysid::{N4sidSettings, PemSettings, n4sid, pem, synthetic};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let truth = synthetic::random_model(8, 4, 3, 8, 0.95);
    let data = synthetic::simulate(&truth, 5000, 0.3, 1).expect("simulate");
    let settings = N4sidSettings {
        order: Some(8),
        ..Default::default()
    };
    let start = n4sid(&data, &settings).expect("n4sid");
    let r = pem(&data, &start.model, &PemSettings::default()).expect("pem");
    eprintln!(
        "pem: {} iterations, {} cost evaluations, cost {:.5} -> {:.5}, stop {:?}",
        r.iterations, r.evaluations, r.initial_cost, r.cost, r.stop
    );
    let mut g = c.benchmark_group("sysid");
    g.sample_size(10);
    g.bench_function("n4sid n=8 nu=4 ny=3 N=5000", |b| {
        b.iter(|| n4sid(black_box(&data), &settings).expect("n4sid"))
    });
    g.bench_function("pem n=8 nu=4 ny=3 N=5000 (from n4sid)", |b| {
        b.iter(|| pem(black_box(&data), &start.model, &PemSettings::default()).expect("pem"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
