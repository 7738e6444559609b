//! Prediction errors with their exact Jacobian by forward sensitivity
//! recursions of the predictor, for one-step, multi-step and simulation
//! errors.

use super::layout::Layout;
use super::residuals::{
    multistep_count, output_error, predictor_state_step, stack_residuals, without_k,
};
use super::series::Series;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};

/// Where one sample's errors go: the first of their `ny` columns of the
/// residual vector and Jacobian, and the experiment (whose own `x0`
/// parameters they depend on).
#[derive(Clone, Copy)]
struct Column {
    col: usize,
    experiment: usize,
}

/// One sample's output error `e = y - C z - D u` (into `e` and the
/// residuals) and its sensitivity `de = -(C dz) - dC z - dD u` (into the
/// Jacobian columns; `cpsi` is scratch), for the state `z` with
/// sensitivity `dz`.
#[allow(clippy::too_many_arguments)]
fn error_and_sensitivity(
    lay: &Layout,
    m: &InnovationModel,
    (z, dz): (&[f64], &DMatrix<f64>),
    (u, y): (&[f64], &[f64]),
    at: Column,
    e: &mut [f64],
    (res, jt): (&mut DVector<f64>, &mut DMatrix<f64>),
    cpsi: &mut DMatrix<f64>,
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    let ps = lay.shared();
    output_error(m, z, (u, y), e);
    res.rows_mut(at.col, ny).copy_from_slice(e);
    cpsi.gemm(-1.0, &m.c, dz, 0.0);
    for o in 0..ny {
        for b in 0..n {
            cpsi[(o, lay.oc + o * n + b)] -= z[b];
        }
        if lay.has_d {
            for b in 0..nu {
                cpsi[(o, lay.od + o * nu + b)] -= u[b];
            }
        }
    }
    for o in 0..ny {
        let mut jc = jt.column_mut(at.col + o);
        for q in 0..ps {
            jc[q] = cpsi[(o, q)];
        }
        for a in 0..n {
            jc[lay.ox + at.experiment * n + a] = cpsi[(o, ps + a)];
        }
    }
}

/// One predictor step with its sensitivity:
/// `Psi+ = Abar Psi + dA x + dB u + dK e - K (dC x + dD u)` and
/// `x+ = A x + B u + K e` (`xn`, `psin` are scratch; the results are
/// swapped into `x`, `psi`).
fn advance_predictor(
    lay: &Layout,
    m: &InnovationModel,
    abar: &DMatrix<f64>,
    (u, e): (&[f64], &[f64]),
    (x, xn): (&mut Vec<f64>, &mut Vec<f64>),
    (psi, psin): (&mut DMatrix<f64>, &mut DMatrix<f64>),
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    psin.gemm(1.0, abar, psi, 0.0);
    for a in 0..n {
        for b in 0..n {
            psin[(a, a * n + b)] += x[b];
        }
        for b in 0..nu {
            psin[(a, lay.ob + a * nu + b)] += u[b];
        }
        if lay.has_k {
            for b in 0..ny {
                psin[(a, lay.ok + a * ny + b)] += e[b];
            }
        }
    }
    for o in 0..ny {
        for b in 0..n {
            let c = lay.oc + o * n + b;
            let xb = x[b];
            for a in 0..n {
                psin[(a, c)] -= m.k[(a, o)] * xb;
            }
        }
        if lay.has_d {
            for b in 0..nu {
                let c = lay.od + o * nu + b;
                for a in 0..n {
                    psin[(a, c)] -= m.k[(a, o)] * u[b];
                }
            }
        }
    }
    std::mem::swap(psi, psin);
    predictor_state_step(m, x, u, e, xn);
    std::mem::swap(x, xn);
}

/// Prediction errors and the transposed Jacobian `d e / d theta` (`p x M`)
/// by forward sensitivity recursions of the predictor:
/// `Psi+ = (A - KC) Psi + dA x + dB u + dK e - K (dC x + dD u)`,
/// `de = -(C Psi + dC x + dD u)`.
///
/// With horizon `h > 1` (multi-step focus): for every `t` the errors of
/// the `1..=h`-step-ahead predictions made from the predictor state
/// `x(t|t-1)` (`z0 = x, z+ = A z + B u`, error `y - C z - D u`), stacked
/// `[t][step][output]` (steps that run past the end of an experiment are
/// left out), and their exact Jacobian: the look-ahead sensitivities
/// `dz0 = Psi`, `dz+ = A dz + dA z + dB u`, `de = -(C dz + dC z + dD u)`.
/// `h = 1` gives the one-step errors.
pub(super) fn residuals_and_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    h: usize,
) -> (DVector<f64>, DMatrix<f64>) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    let total: usize = data.iter().map(|s| multistep_count(s.n, h) * ny).sum();
    let mut z = vec![0.0; n];
    let mut zn = vec![0.0; n];
    let mut dz = DMatrix::<f64>::zeros(n, 0);
    let mut dzn = DMatrix::<f64>::zeros(n, 0);
    let mut res = DVector::zeros(total);
    let mut jt = DMatrix::<f64>::zeros(lay.p, total);
    let ps = lay.shared();
    let pl = ps + n; // shared + own x0
    let abar = &m.a - &m.k * &m.c;
    let mut psi = DMatrix::<f64>::zeros(n, pl);
    let mut psin = DMatrix::<f64>::zeros(n, pl);
    let mut cpsi = DMatrix::<f64>::zeros(ny, pl);
    let mut col = 0;
    let mut x = vec![0.0; n];
    let mut xn = vec![0.0; n];
    let mut e = vec![0.0; ny];
    let mut ej = vec![0.0; ny];
    for (ei, (s, x0e)) in data.iter().zip(x0).enumerate() {
        x.copy_from_slice(x0e.as_slice());
        psi.fill(0.0);
        for a in 0..n {
            psi[(a, ps + a)] = 1.0;
        }
        for t in 0..s.n {
            let u = &s.u[t * nu..(t + 1) * nu];
            let y = &s.y[t * ny..(t + 1) * ny];
            let at = Column {
                col,
                experiment: ei,
            };
            error_and_sensitivity(
                lay,
                m,
                (&x, &psi),
                (u, y),
                at,
                &mut e,
                (&mut res, &mut jt),
                &mut cpsi,
            );
            // Look ahead: steps 2..=h from z0 = x, dz0 = Psi.
            if h > 1 {
                z.copy_from_slice(&x);
                dz.clone_from(&psi);
                dzn.clone_from(&psi);
            }
            for j in 1..h.min(s.n - t) {
                let up = &s.u[(t + j - 1) * nu..(t + j) * nu];
                dzn.gemm(1.0, &m.a, &dz, 0.0);
                for a in 0..n {
                    for b in 0..n {
                        dzn[(a, a * n + b)] += z[b];
                    }
                    for b in 0..nu {
                        dzn[(a, lay.ob + a * nu + b)] += up[b];
                    }
                }
                std::mem::swap(&mut dz, &mut dzn);
                predictor_state_step(m, &z, up, &[], &mut zn);
                std::mem::swap(&mut z, &mut zn);
                let uj = &s.u[(t + j) * nu..(t + j + 1) * nu];
                let yj = &s.y[(t + j) * ny..(t + j + 1) * ny];
                let at = Column {
                    col: col + j * ny,
                    experiment: ei,
                };
                error_and_sensitivity(
                    lay,
                    m,
                    (&z, &dz),
                    (uj, yj),
                    at,
                    &mut ej,
                    (&mut res, &mut jt),
                    &mut cpsi,
                );
            }
            advance_predictor(
                lay,
                m,
                &abar,
                (u, &e),
                (&mut x, &mut xn),
                (&mut psi, &mut psin),
            );
            col += ny * h.min(s.n - t);
        }
    }
    (res, jt)
}

/// The simulation term of [`PemSettings::simulation_weight`]: the errors
/// `y - C x - D u` of `x+ = A x + B u` from the initial states `xs`
/// (sample-major like [`residuals`]) and their transposed Jacobian in the
/// layout `lay` (rows of `A, B, C, D` and of the simulation initial
/// states; `K` and the predictor's initial states do not enter). The
/// sensitivities are those of [`Focus::Simulation`]: the one-step
/// recursion with `K = 0`.
pub(super) fn simulation_residuals_and_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    xs: &[DVector<f64>],
    data: &[Series],
) -> (DVector<f64>, DMatrix<f64>) {
    let sl = Layout::new(lay.n, lay.nu, lay.ny, lay.ne, lay.has_d, false);
    let (r, js) = residuals_and_jacobian(&sl, &without_k(m), xs, data, 1);
    let mut jt = DMatrix::zeros(lay.p, r.len());
    // A, B, C, [D] come first in both layouts (sl.ox == lay.ok).
    jt.rows_mut(0, sl.ox).copy_from(&js.rows(0, sl.ox));
    let nx0 = lay.n * lay.ne;
    jt.rows_mut(lay.osx, nx0).copy_from(&js.rows(sl.ox, nx0));
    (r, jt)
}

/// Residuals `[a; b]` and transposed Jacobians `[ja, jb]` side by side.
pub(super) fn stack(
    (a, ja): (DVector<f64>, DMatrix<f64>),
    (b, jb): (DVector<f64>, DMatrix<f64>),
) -> (DVector<f64>, DMatrix<f64>) {
    let (na, nb) = (a.len(), b.len());
    let r = stack_residuals(a, &b);
    let mut j = ja.resize_horizontally(na + nb, 0.0);
    j.columns_mut(na, nb).copy_from(&jb);
    (r, j)
}
