//! The residuals and their exact Jacobian against central differences,
//! the similarity directions and the fit criterion's groups.

use super::super::criterion::{fit_groups, fit_weights};
use super::super::jacobian::{residuals_and_jacobian, simulation_residuals_and_jacobian, stack};
use super::super::layout::Layout;
use super::super::residuals::{
    multistep_count, multistep_residuals, residuals, stack_residuals, without_k,
};
use super::super::search::pem;
use super::super::series::{Series, series_of};
use super::super::settings::{Focus, PemSettings};
use crate::data::IoData;
use crate::error::SysidError;
use crate::model::InnovationModel;
use crate::synthetic;
use nalgebra::{DMatrix, DVector};

/// The set-up of the Jacobian checks: a random stable 3-state,
/// 2-input, 2-output model `m`, `samples` samples of its data (noise
/// seed `noise_seed`) merged twice into two experiments, `m` with a
/// feed-through `D` (`base`) and two predictor initial states.
struct JacobianFixture {
    m: InnovationModel,
    data: IoData,
    series: Vec<Series>,
    base: InnovationModel,
    x0: Vec<DVector<f64>>,
}

fn jacobian_fixture(seed: u64, samples: usize, noise_seed: u64) -> JacobianFixture {
    let m = synthetic::random_model(3, 2, 2, seed, 0.8);
    let data = synthetic::simulate(&m, samples, 0.3, noise_seed).unwrap();
    let sdata = IoData::merge(&[data.clone(), data.clone()]).unwrap();
    let series = series_of(&sdata);
    let mut base = m.clone();
    base.d = DMatrix::from_fn(2, 2, |i, j| 0.1 * (i + 2 * j) as f64);
    let x0 = vec![
        DVector::from_vec(vec![0.3, -0.2, 0.1]),
        DVector::from_vec(vec![0.0, 0.5, -0.4]),
    ];
    JacobianFixture {
        m,
        data,
        series,
        base,
        x0,
    }
}

/// The transposed Jacobian of `f` at `th` (a row per parameter) by
/// central differences of step `1e-6`.
fn central_differences(
    th: &DVector<f64>,
    f: impl Fn(&DVector<f64>) -> DVector<f64>,
) -> DMatrix<f64> {
    let eps = 1e-6;
    let rows: Vec<_> = (0..th.len())
        .map(|j| {
            let mut tp = th.clone();
            tp[j] += eps;
            let mut tm = th.clone();
            tm[j] -= eps;
            ((f(&tp) - f(&tm)) / (2.0 * eps)).transpose()
        })
        .collect();
    DMatrix::from_rows(&rows)
}

/// Every row of the exact transposed Jacobian `jt` agrees with that
/// of `fd` within `1e-6 (1 + |row|)`.
fn assert_rows_agree(jt: &DMatrix<f64>, fd: &DMatrix<f64>, label: &str) {
    assert_eq!(jt.shape(), fd.shape(), "{label}");
    for j in 0..jt.nrows() {
        let an = jt.row(j);
        let err = (fd.row(j) - an).norm();
        assert!(err < 1e-6 * (1.0 + an.norm()), "{label}param {j}: {err}");
    }
}

#[test]
fn jacobian_matches_central_differences() {
    let JacobianFixture {
        series, base, x0, ..
    } = jacobian_fixture(21, 60, 5);
    for (has_d, has_k) in [(true, true), (false, false)] {
        let lay = Layout::new(3, 2, 2, 2, has_d, has_k);
        let th = lay.pack(&base, &x0);
        let (mm, xx) = lay.unpack(&th, &base);
        let (r0, jt) = residuals_and_jacobian(&lay, &mm, &xx, &series, 1);
        let res = |th: &DVector<f64>| {
            let (mm, xx) = lay.unpack(th, &base);
            residuals(&mm, &xx, &series)
        };
        assert!((&r0 - res(&th)).norm() < 1e-12);
        assert_rows_agree(&jt, &central_differences(&th, res), "");
    }
}

/// The multi-step errors and their Jacobian: horizon 1 is the one-step
/// predictor, the errors agree with an independent k-step prediction
/// ([`InnovationModel::predict_k_step`]), and the Jacobian with central
/// differences.
#[test]
fn multistep_jacobian_matches_central_differences() {
    let JacobianFixture {
        m,
        data,
        series,
        base,
        x0,
    } = jacobian_fixture(23, 40, 6);
    let one = residuals(&base, &x0, &series);
    assert!((multistep_residuals(&base, &x0, &series, 1) - &one).norm() < 1e-12);
    // Step k of sample t against predict_k_step (the k-step
    // prediction of y(t + k - 1) made at t - 1), first experiment.
    let h = 3;
    let ms = multistep_residuals(&base, &x0, &series, h);
    let e0 = &data.experiments()[0];
    for k in 1..=h {
        let p = base.predict_k_step(&e0.u, &e0.y, &x0[0], k).unwrap();
        for t in 1..(40 - h) {
            for o in 0..2 {
                let want = e0.y[(t + k - 1, o)] - p[(t + k - 1, o)];
                let got = ms[(t * h + (k - 1)) * 2 + o];
                assert!((want - got).abs() < 1e-10, "t {t} k {k}: {want} vs {got}");
            }
        }
    }
    for (has_d, has_k) in [(true, true), (false, true)] {
        let lay = Layout::new(3, 2, 2, 2, has_d, has_k);
        let th = lay.pack(&base, &x0);
        let (mm, xx) = lay.unpack(&th, &base);
        let (r0, jt) = residuals_and_jacobian(&lay, &mm, &xx, &series, h);
        let res = |th: &DVector<f64>| {
            let (mm, xx) = lay.unpack(th, &base);
            multistep_residuals(&mm, &xx, &series, h)
        };
        assert!((&r0 - res(&th)).norm() < 1e-12);
        assert_rows_agree(&jt, &central_differences(&th, res), "");
    }
    // The horizon is checked.
    for (focus, horizon) in [(Focus::Prediction, 0), (Focus::Simulation, 2)] {
        let s = PemSettings {
            focus,
            horizon,
            ..Default::default()
        };
        assert!(matches!(
            pem(&data, &m, &s),
            Err(SysidError::InvalidArgument(_))
        ));
    }
}

#[test]
fn similarity_directions_leave_the_predictor_unchanged() {
    let m = synthetic::random_model(3, 2, 2, 4, 0.8);
    let lay = Layout::new(3, 2, 2, 1, false, true);
    let x0 = vec![DVector::from_vec(vec![0.1, 0.2, 0.3])];
    let qp = lay.ddlc(&m, &x0, &[]);
    assert_eq!(qp.ncols(), lay.p - 9);
    // With a simulation term its initial states move along too.
    let ls = lay.with_simulation();
    let xs = vec![DVector::from_vec(vec![-0.3, 0.1, 0.2])];
    let qs = ls.ddlc(&m, &x0, &xs);
    assert_eq!(qs.ncols(), ls.p - 9);
    let mut th0 = ls.pack(&m, &x0);
    ls.pack_simulation(&mut th0, &xs);
    let ti = DMatrix::<f64>::identity(3, 3)
        + DMatrix::from_fn(3, 3, |i, j| 0.01 * ((i + 2 * j) as f64).cos());
    let tinv = ti.clone().try_inverse().unwrap();
    let mut th1 = ls.pack(&m.transform(&ti).unwrap(), &[&tinv * &x0[0]]);
    ls.pack_simulation(&mut th1, &[&tinv * &xs[0]]);
    let d = th1 - th0;
    assert!((qs.transpose() * &d).norm() < 0.05 * d.norm());
    // The complement is orthogonal to the tangent of a similarity.
    let t = DMatrix::from_fn(3, 3, |i, j| 0.01 * ((i * 3 + j) as f64).sin());
    let ti = DMatrix::<f64>::identity(3, 3) + &t;
    let mt = m.transform(&ti).unwrap();
    let x0t = vec![ti.clone().try_inverse().unwrap() * &x0[0]];
    let d = lay.pack(&mt, &x0t) - lay.pack(&m, &x0);
    let inplane = qp.transpose() * &d;
    assert!(
        inplane.norm() < 0.05 * d.norm(),
        "{} vs {}",
        inplane.norm(),
        d.norm()
    );
}

/// The fit criterion's groups follow the residual layout of the
/// multi-step criterion (steps past an experiment's end left out).
#[test]
fn fit_groups_follow_the_multistep_layout() {
    let m = synthetic::random_model(2, 1, 2, 5, 0.8);
    let a = synthetic::simulate(&m, 7, 0.1, 1).unwrap();
    let b = synthetic::simulate(&m, 4, 0.1, 2).unwrap();
    let series = series_of(&IoData::merge(&[a, b]).unwrap());
    let x0 = vec![DVector::zeros(2), DVector::zeros(2)];
    for h in [1, 3, 5] {
        let g = fit_groups(&series, 2, h);
        assert_eq!(g.len(), multistep_residuals(&m, &x0, &series, h).len());
        // The second experiment (4 samples), h = 3: steps 1,2,3 | 1,2,3 | 1,2 | 1.
        let tail: Vec<usize> = g[g.len() - 2 * multistep_count(4, h)..]
            .iter()
            .step_by(2)
            .copied()
            .collect();
        let want: Vec<usize> = (0..4)
            .flat_map(|t: usize| (0..h.min(4 - t)).map(|j| 2 * j))
            .collect();
        assert_eq!(tail, want, "h = {h}");
    }
    // Weights are 1 / rms per group.
    let res = DVector::from_vec(vec![3.0, 1.0, -3.0, 2.0]);
    let w = fit_weights(&res, &[0, 1, 0, 1], 2);
    assert!((w[0] - 1.0 / 3.0).abs() < 1e-15);
    assert!((w[1] - 1.0 / 2.5f64.sqrt()).abs() < 1e-15);
}

/// The combined criterion's residuals: the prediction errors, then
/// the simulation errors, which agree with an independent simulation
/// ([`InnovationModel::simulate`], `K` unused) from the simulation
/// term's own initial states; the stacked Jacobian agrees with central
/// differences (`K` and the predictor's `x0` do not move the
/// simulation errors, the simulation `x0` does not move the
/// prediction errors).
#[test]
fn simulation_term_jacobian_matches_central_differences() {
    let JacobianFixture {
        data,
        series,
        base,
        x0,
        ..
    } = jacobian_fixture(41, 30, 7);
    let xs = vec![
        DVector::from_vec(vec![-0.1, 0.4, 0.2]),
        DVector::from_vec(vec![0.6, -0.3, 0.0]),
    ];
    let e0 = &data.experiments()[0];
    let want = &e0.y - base.simulate(&e0.u, &xs[0]).unwrap();
    let got = residuals(&without_k(&base), &xs, &series);
    for t in 0..30 {
        for o in 0..2 {
            assert!((want[(t, o)] - got[t * 2 + o]).abs() < 1e-12);
        }
    }
    for (has_d, h) in [(true, 1), (false, 3)] {
        let lay = Layout::new(3, 2, 2, 2, has_d, true).with_simulation();
        let mut th = lay.pack(&base, &x0);
        lay.pack_simulation(&mut th, &xs);
        let all = |th: &DVector<f64>| {
            let (mm, xx) = lay.unpack(th, &base);
            let ss = lay.simulation_x0(th);
            stack_residuals(
                multistep_residuals(&mm, &xx, &series, h),
                &residuals(&without_k(&mm), &ss, &series),
            )
        };
        let (mm, xx) = lay.unpack(&th, &base);
        assert_eq!(lay.simulation_x0(&th), xs);
        let (r0, jt) = stack(
            residuals_and_jacobian(&lay, &mm, &xx, &series, h),
            simulation_residuals_and_jacobian(&lay, &mm, &xs, &series),
        );
        assert_eq!(jt.nrows(), lay.p);
        assert!((&r0 - all(&th)).norm() < 1e-12);
        let n_pred = r0.len() - 2 * 60;
        let fd = central_differences(&th, all);
        assert_rows_agree(&jt, &fd, &format!("h {h} "));
        for j in 0..lay.p {
            let (an, fd) = (jt.row(j), fd.row(j));
            // K and the predictor's x0 leave the simulation alone; the
            // simulation x0 leaves the prediction alone.
            if (lay.ok..lay.osx).contains(&j) {
                assert!(an.columns(n_pred, 120).amax() == 0.0);
                assert!(fd.columns(n_pred, 120).amax() < 1e-9);
            }
            if j >= lay.osx {
                assert!(an.columns(0, n_pred).amax() == 0.0);
                assert!(fd.columns(0, n_pred).amax() < 1e-9);
            }
        }
    }
}
