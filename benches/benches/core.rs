//! Benchmarks of the kestrel-core kernels in f64, f32 and fixed point, and of `c2d`.

use criterion::{Criterion, criterion_group, criterion_main};
use kestrel_benches::pseudo_random;
use kestrel_core::{Matrix, Q16, Scalar, c2d};
use std::hint::black_box;

fn mat<S: Scalar, const R: usize, const C: usize>(seed: u64) -> Matrix<S, R, C> {
    let v = pseudo_random(seed, R * C);
    Matrix::from_fn(|i, j| S::from_f64(v[i * C + j]))
}

fn bench_mul_vec<S: Scalar>(c: &mut Criterion, name: &str) {
    let a = mat::<S, 8, 8>(1);
    let x: [S; 8] = core::array::from_fn(|i| S::from_f64(pseudo_random(2, 8)[i]));
    c.bench_function(&format!("mul_vec 8x8 {name}"), |b| {
        b.iter(|| black_box(&a).mul_vec(black_box(&x)))
    });
}

fn kernels(c: &mut Criterion) {
    bench_mul_vec::<f64>(c, "f64");
    bench_mul_vec::<f32>(c, "f32");
    bench_mul_vec::<Q16>(c, "q16");
    let a = nalgebra::DMatrix::from_row_slice(8, 8, &pseudo_random(3, 64));
    let b = nalgebra::DMatrix::from_row_slice(8, 4, &pseudo_random(4, 32));
    c.bench_function("c2d n=8 m=4", |bch| {
        bch.iter(|| c2d(black_box(&a), black_box(&b), 0.02))
    });
}

criterion_group!(benches, kernels);
criterion_main!(benches);
