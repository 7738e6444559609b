//! The structured Jacobian rows against the dense sensitivity recursions
//! they replace, and the accumulated normal equations against the
//! product of the whole weighted Jacobian.

use super::super::criterion::Objective;
use super::super::jacobian::{residuals_and_jacobian, simulation_residuals_and_jacobian, stack};
use super::super::layout::Layout;
use super::super::normal::normal_equations;
use super::super::residuals::{multistep_residuals, residuals, stack_residuals, without_k};
use super::super::series::{Series, series_of};
use super::super::settings::{Criterion, PemSettings};
use crate::model::InnovationModel;
use crate::synthetic;
use nalgebra::{DMatrix, DVector};

/// `dM v`: the `rows x p` sensitivity of `M v` to the entries of `M`
/// (`rows x v.len()`, row-major at `offset` of the layout).
fn d_times(rows: usize, v: &[f64], offset: usize, p: usize) -> DMatrix<f64> {
    let mut d = DMatrix::zeros(rows, p);
    for a in 0..rows {
        for (b, vb) in v.iter().enumerate() {
            d[(a, offset + a * v.len() + b)] = *vb;
        }
    }
    d
}

/// The transposed Jacobian by the dense recursions: the one-step
/// sensitivity `Psi` (`n x p`) and, for every step ahead, the dense
/// look-ahead `dz+ = A dz + dA z + dB u`.
fn dense_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    h: usize,
) -> DMatrix<f64> {
    let (n, nu, ny, p) = (lay.n, lay.nu, lay.ny, lay.p);
    let dd = |u: &[f64]| {
        if lay.has_d {
            d_times(ny, u, lay.od, p)
        } else {
            DMatrix::zeros(ny, p)
        }
    };
    let mut cols = Vec::new();
    let abar = &m.a - &m.k * &m.c;
    for (ei, (s, x0e)) in data.iter().zip(x0).enumerate() {
        let mut x = x0e.clone();
        let mut psi = DMatrix::<f64>::zeros(n, p);
        for a in 0..n {
            psi[(a, lay.ox + ei * n + a)] = 1.0;
        }
        for t in 0..s.n {
            let ut = DVector::from_column_slice(&s.u[t * nu..(t + 1) * nu]);
            let yt = DVector::from_column_slice(&s.y[t * ny..(t + 1) * ny]);
            let e = &yt - &m.c * &x - &m.d * &ut;
            let (mut z, mut dz) = (x.clone(), psi.clone());
            for j in 0..h.min(s.n - t) {
                let uj = &s.u[(t + j) * nu..(t + j + 1) * nu];
                if j > 0 {
                    let up = &s.u[(t + j - 1) * nu..(t + j) * nu];
                    dz = &m.a * &dz + d_times(n, z.as_slice(), 0, p) + d_times(n, up, lay.ob, p);
                    z = &m.a * &z + &m.b * DVector::from_column_slice(up);
                }
                let de = -(&m.c * &dz + d_times(ny, z.as_slice(), lay.oc, p) + dd(uj));
                for o in 0..ny {
                    cols.push(de.row(o).transpose());
                }
            }
            let mut next = &abar * &psi
                + d_times(n, x.as_slice(), 0, p)
                + d_times(n, ut.as_slice(), lay.ob, p)
                - &m.k * (d_times(ny, x.as_slice(), lay.oc, p) + dd(ut.as_slice()));
            if lay.has_k {
                next += d_times(n, e.as_slice(), lay.ok, p);
            }
            psi = next;
            x = &m.a * &x + &m.b * &ut + &m.k * &e;
        }
    }
    DMatrix::from_columns(&cols)
}

/// An `n`-state, `nu`-input, `ny`-output model with `D`, two
/// experiments of 40 and 25 samples, two initial states.
fn fixture(n: usize, nu: usize, ny: usize) -> (InnovationModel, Vec<Series>, Vec<DVector<f64>>) {
    let mut m = synthetic::random_model(n, nu, ny, 31, 0.8);
    m.d = DMatrix::from_fn(ny, nu, |i, j| 0.2 * (i + 2 * j) as f64 - 0.3);
    let a = synthetic::simulate(&m, 40, 0.3, 2).unwrap();
    let b = synthetic::simulate(&m, 25, 0.3, 3).unwrap();
    let series = series_of(&crate::data::IoData::merge(&[a, b]).unwrap());
    let x0 = vec![
        DVector::from_fn(n, |i, _| 0.3 - 0.2 * i as f64),
        DVector::from_fn(n, |i, _| (i as f64).sin()),
    ];
    (m, series, x0)
}

/// Largest entry of `a - b` relative to the largest of `b`.
fn rel(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).amax() / b.amax().max(1e-300)
}

/// 3 states (the row-by-row `(A - KC) Psi`) and 6 (one `gemm`).
#[test]
fn structured_rows_equal_the_dense_recursions() {
    for (n, nu, ny) in [(3, 2, 2), (6, 3, 4)] {
        let (m, series, x0) = fixture(n, nu, ny);
        for (has_d, has_k, h) in [
            (true, true, 1),
            (true, true, 4),
            (false, true, 3),
            (false, false, 1),
        ] {
            let lay = Layout::new(n, nu, ny, 2, has_d, has_k);
            let (_, jt) = residuals_and_jacobian(&lay, &m, &x0, &series, h);
            let want = dense_jacobian(&lay, &m, &x0, &series, h);
            let r = rel(&jt, &want);
            assert!(r < 1e-13, "n {n} d {has_d} k {has_k} h {h}: {r:e}");
        }
    }
}

/// `J'J` and `J'r` accumulated block by block equal the products of the
/// whole Jacobian, masked and weighed as the search weighs the
/// residuals: the fit criterion with steps left out and a simulation
/// term, and the determinant criterion's whitening; 3 states (one
/// Hessian block) and 6 states with 4 outputs (120 compact columns,
/// two blocks).
#[test]
fn accumulated_normal_equations_equal_the_whole_jacobian_products() {
    for (n, nu, ny) in [(3, 2, 2), (6, 3, 4)] {
        normal_equations_match(n, nu, ny);
    }
}

fn normal_equations_match(n: usize, nu: usize, ny: usize) {
    let (m, series, x0) = fixture(n, nu, ny);
    let xs = vec![
        DVector::from_fn(n, |i, _| (i as f64).cos()),
        DVector::from_fn(n, |i, _| 0.1 * i as f64 - 0.2),
    ];
    let cases = [
        (Criterion::Fit, 4, vec![1, 4], 0.5),
        (Criterion::Trace, 3, vec![], 0.0),
        (Criterion::Determinant, 2, vec![2], 0.0),
        (Criterion::Trace, 1, vec![], 2.0),
    ];
    for (criterion, h, steps, ws) in cases {
        let settings = PemSettings {
            criterion,
            horizon: h,
            steps: steps.clone(),
            simulation_weight: ws,
            ..Default::default()
        };
        let mut lay = Layout::new(n, nu, ny, 2, true, true);
        let sim = ws > 0.0;
        if sim {
            lay = lay.with_simulation();
        }
        let xs: &[DVector<f64>] = if sim { &xs } else { &[] };
        let objective = Objective::new(&settings, &series, ny);
        let (mut r, mut jt) = residuals_and_jacobian(&lay, &m, &x0, &series, h);
        let mut r1 = multistep_residuals(&m, &x0, &series, h);
        if sim {
            (r, jt) = stack(
                (r, jt),
                simulation_residuals_and_jacobian(&lay, &m, xs, &series),
            );
            r1 = stack_residuals(r1, &residuals(&without_k(&m), xs, &series));
        }
        assert_eq!(r, r1);
        objective.mask(&mut r);
        objective.mask_jacobian(&mut jt);
        let w = objective.weights_at(&r);
        w.apply(&objective.groups, &mut r);
        w.apply_to_jacobian(&objective.groups, &mut jt);
        let (hs, g) = normal_equations(&lay, &m, (&x0, xs), &series, h, &objective, &w, &r);
        let label = format!("n {n}: {criterion:?} h {h} steps {steps:?} ws {ws}");
        let hr = rel(&hs, &(&jt * jt.transpose()));
        assert!(hr < 1e-13, "{label}: J'J {hr:e}");
        let gr = (&g - &jt * &r).amax() / (&jt * &r).amax();
        assert!(gr < 1e-13, "{label}: J'r {gr:e}");
    }
}
