//! Benchmarks of kestrel-kalman: `dare` at n = 5, 20, 60 (target: 20x faster
//! than SciPy's `solve_discrete_are` for n <= 20, i.e. < ~23 us at n = 5,
//! and 5x at n = 60, i.e. < ~7.8 ms), and the stationary filter step.
//!
//! The DARE problems: `A` pseudo-random with spectral radius about 1.1
//! (a few unstable modes), `B` `n x (1 + n/4)` pseudo-random, `Q = C'C`
//! with `C` `(1 + n/3) x n` pseudo-random, `R = I`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use kestrel_benches::pseudo_random;
use kestrel_kalman::{DareSettings, DetectabilityCheck, dare, dare_with};
use nalgebra::DMatrix;
use std::hint::black_box;

struct Problem {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
}

fn problem(n: usize) -> Problem {
    let m = 1 + n / 4;
    let p = 1 + n / 3;
    // Uniform [-1, 1) has variance 1/3: scale to a spectral radius near 1.1.
    let scale = 1.1 * 3f64.sqrt() / (n as f64).sqrt();
    let a = DMatrix::from_row_slice(n, n, &pseudo_random(11 + n as u64, n * n)) * scale;
    let b = DMatrix::from_row_slice(n, m, &pseudo_random(23 + n as u64, n * m));
    let c = DMatrix::from_row_slice(p, n, &pseudo_random(37 + n as u64, p * n));
    Problem {
        a,
        b,
        q: c.transpose() * c,
        r: DMatrix::identity(m, m),
    }
}

fn bench_dare(c: &mut Criterion) {
    let mut group = c.benchmark_group("dare");
    for n in [5usize, 20, 60] {
        let p = problem(n);
        let sol = dare(&p.a, &p.b, &p.q, &p.r, None).expect("benchmark problem solvable");
        eprintln!(
            "dare n={n}: {} doubling steps, {} refinements, residual {:.1e}",
            sol.iterations, sol.refinements, sol.residual
        );
        group.bench_with_input(BenchmarkId::new("default", n), &p, |bch, p| {
            bch.iter(|| dare(black_box(&p.a), black_box(&p.b), &p.q, &p.r, None))
        });
        let always = DareSettings {
            detectability: DetectabilityCheck::Always,
            ..DareSettings::default()
        };
        group.bench_with_input(BenchmarkId::new("pbh_always", n), &p, |bch, p| {
            bch.iter(|| dare_with(black_box(&p.a), black_box(&p.b), &p.q, &p.r, None, &always))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_dare);
criterion_main!(benches);
