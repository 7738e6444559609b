//! Prediction errors of the innovation model without derivatives (the
//! cost of a trial step): one-step, multi-step and simulation errors.

use super::series::Series;
use crate::model::InnovationModel;
use nalgebra::DVector;

/// Prediction errors of the model (all experiments stacked, sample-major).
pub(super) fn residuals(m: &InnovationModel, x0: &[DVector<f64>], data: &[Series]) -> DVector<f64> {
    let (n, nu, ny) = (m.nx(), m.nu(), m.ny());
    let total: usize = data.iter().map(|s| s.n * ny).sum();
    let mut out = DVector::zeros(total);
    let mut row = 0;
    let mut x = vec![0.0; n];
    let mut xn = vec![0.0; n];
    let mut e = vec![0.0; ny];
    for (s, x0e) in data.iter().zip(x0) {
        x.copy_from_slice(x0e.as_slice());
        for t in 0..s.n {
            let u = &s.u[t * nu..(t + 1) * nu];
            let y = &s.y[t * ny..(t + 1) * ny];
            output_error(m, &x, (u, y), &mut e);
            out.rows_mut(row, ny).copy_from_slice(&e);
            predictor_state_step(m, &x, u, &e, &mut xn);
            std::mem::swap(&mut x, &mut xn);
            row += ny;
        }
    }
    out
}

/// The predictor's output error `e = y - C x - D u`.
pub(super) fn output_error(
    m: &InnovationModel,
    x: &[f64],
    (u, y): (&[f64], &[f64]),
    e: &mut [f64],
) {
    for (o, eo) in e.iter_mut().enumerate() {
        let mut v = y[o];
        for (i, xi) in x.iter().enumerate() {
            v -= m.c[(o, i)] * xi;
        }
        for (j, uj) in u.iter().enumerate() {
            v -= m.d[(o, j)] * uj;
        }
        *eo = v;
    }
}

/// The predictor's state step `xn = A x + B u + K e` (with `e` empty the
/// look-ahead step `A x + B u`).
pub(super) fn predictor_state_step(
    m: &InnovationModel,
    x: &[f64],
    u: &[f64],
    e: &[f64],
    xn: &mut [f64],
) {
    for (i, xi) in xn.iter_mut().enumerate() {
        let mut v = 0.0;
        for (j, xj) in x.iter().enumerate() {
            v += m.a[(i, j)] * xj;
        }
        for (j, uj) in u.iter().enumerate() {
            v += m.b[(i, j)] * uj;
        }
        for (o, eo) in e.iter().enumerate() {
            v += m.k[(i, o)] * eo;
        }
        *xi = v;
    }
}

/// Number of multi-step errors per output of an experiment of `len`
/// samples with horizon `h` (steps past the end left out).
pub(super) fn multistep_count(len: usize, h: usize) -> usize {
    (0..len).map(|t| h.min(len - t)).sum()
}

/// Multi-step prediction errors (the errors whose Jacobian
/// [`sensitivity_rows`](super::jacobian::sensitivity_rows) gives, in the
/// same `[t][step][output]` order and by the same arithmetic); `h = 1`
/// gives [`residuals`].
pub(super) fn multistep_residuals(
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    h: usize,
) -> DVector<f64> {
    let (n, nu, ny) = (m.nx(), m.nu(), m.ny());
    let total: usize = data.iter().map(|s| multistep_count(s.n, h) * ny).sum();
    let mut out = DVector::zeros(total);
    let mut row = 0;
    let mut x = vec![0.0; n];
    let mut xn = vec![0.0; n];
    let mut z = vec![0.0; n];
    let mut zn = vec![0.0; n];
    let mut e = vec![0.0; ny];
    for (s, x0e) in data.iter().zip(x0) {
        x.copy_from_slice(x0e.as_slice());
        for t in 0..s.n {
            let u = &s.u[t * nu..(t + 1) * nu];
            let y = &s.y[t * ny..(t + 1) * ny];
            output_error(m, &x, (u, y), &mut e);
            out.rows_mut(row, ny).copy_from_slice(&e);
            row += ny;
            z.copy_from_slice(&x);
            for j in 1..h.min(s.n - t) {
                let up = &s.u[(t + j - 1) * nu..(t + j) * nu];
                predictor_state_step(m, &z, up, &[], &mut zn);
                std::mem::swap(&mut z, &mut zn);
                let uj = &s.u[(t + j) * nu..(t + j + 1) * nu];
                let yj = &s.y[(t + j) * ny..(t + j + 1) * ny];
                output_error(m, &z, (uj, yj), &mut out.as_mut_slice()[row..row + ny]);
                row += ny;
            }
            predictor_state_step(m, &x, u, &e, &mut xn);
            std::mem::swap(&mut x, &mut xn);
        }
    }
    out
}

/// The model with `K = 0`: the simulation (output-error) model of the
/// same `A, B, C, D`.
pub(super) fn without_k(m: &InnovationModel) -> InnovationModel {
    let mut m0 = m.clone();
    m0.k.fill(0.0);
    m0
}

/// Residuals `[a; b]`.
pub(super) fn stack_residuals(a: DVector<f64>, b: &DVector<f64>) -> DVector<f64> {
    let na = a.len();
    let mut r = a.resize_vertically(na + b.len(), 0.0);
    r.rows_mut(na, b.len()).copy_from(b);
    r
}
