//! Validation and preprocessing: `H` positive definite, finite parameter
//! bounds, normalised constraint rows, exact duplicates removed and
//! constraints without `z` moved to the parameter set.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::mpqp::settings::Settings;
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};

/// The problem after validation and preprocessing.
pub(super) struct Prepared {
    pub n: usize,
    pub p: usize,
    pub m: usize,
    pub h: DMatrix<f64>,
    pub hinv: DMatrix<f64>,
    /// `F`, `p x n`.
    pub ft: DMatrix<f64>,
    pub f: DVector<f64>,
    pub g: DMatrix<f64>,
    pub w: DVector<f64>,
    pub e: DMatrix<f64>,
    /// Reduced row -> original row.
    pub kept: Vec<usize>,
    pub param_a: DMatrix<f64>,
    pub param_b: DVector<f64>,
    pub hinv_gt: DMatrix<f64>,
    pub hinv_ft: DMatrix<f64>,
    pub hinv_f: DVector<f64>,
    pub scale: f64,
    pub radius_tol: f64,
    pub duplicates: usize,
    pub theta_lb: DVector<f64>,
    pub theta_ub: DVector<f64>,
}

pub(super) fn prepare(prob: &MpqpProblem, settings: &Settings) -> Result<Prepared, EmpcError> {
    if let Some(j) = (0..prob.theta_lb.len().min(prob.theta_ub.len()))
        .find(|&j| !prob.theta_lb[j].is_finite() || !prob.theta_ub[j].is_finite())
    {
        return Err(EmpcError::UnboundedParameterSet(format!(
            "theta_lb[{j}] = {}, theta_ub[{j}] = {}: every parameter needs finite bounds",
            prob.theta_lb[j], prob.theta_ub[j]
        )));
    }
    prob.validate()?;
    if let Some(j) =
        (0..prob.p()).find(|&j| prob.theta_lb[j].abs().max(prob.theta_ub[j].abs()) > 1e12)
    {
        return Err(EmpcError::UnboundedParameterSet(format!(
            "theta bound {j} has magnitude above 1e12; give a realistic box"
        )));
    }
    if !(settings.radius_tol > 0.0 && settings.step > 0.0) {
        return Err(EmpcError::InvalidArgument(
            "radius_tol and step must be positive".into(),
        ));
    }
    let (n, p) = (prob.n(), prob.p());
    if n == 0 || p == 0 {
        return Err(EmpcError::InvalidArgument(
            "the problem needs at least one variable and one parameter".into(),
        ));
    }
    // H positive definite.
    let hmax = prob.h.amax().max(f64::MIN_POSITIVE);
    let chol = prob
        .h
        .clone()
        .cholesky()
        .ok_or(EmpcError::IndefiniteHessian {
            min_pivot: f64::NAN,
        })?;
    let min_pivot = (0..n)
        .map(|i| chol.l()[(i, i)].powi(2))
        .fold(f64::INFINITY, f64::min);
    if min_pivot <= 1e-12 * hmax {
        return Err(EmpcError::IndefiniteHessian { min_pivot });
    }
    let hinv = chol.inverse();
    let scale = 1.0
        + (0..p)
            .map(|j| prob.theta_lb[j].abs().max(prob.theta_ub[j].abs()))
            .fold(0.0, f64::max);
    // Parameter set: box and optional polytope.
    let mut prow: Vec<(Vec<f64>, f64)> = Vec::new();
    for j in 0..p {
        let mut a = vec![0.0; p];
        a[j] = 1.0;
        prow.push((a.clone(), prob.theta_ub[j]));
        a[j] = -1.0;
        prow.push((a, -prob.theta_lb[j]));
    }
    if let Some((pa, pb)) = &prob.theta_poly {
        for i in 0..pa.nrows() {
            let a: Vec<f64> = pa.row(i).iter().copied().collect();
            let nrm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            if nrm <= 1e-12 {
                if pb[i] < 0.0 {
                    return Err(EmpcError::EmptyFeasibleSet);
                }
                continue;
            }
            prow.push((a.iter().map(|v| v / nrm).collect(), pb[i] / nrm));
        }
    }
    // Constraint rows: normalise, move z-free rows to the parameter set, drop duplicates.
    let gmax = prob.g.amax().max(1e-300);
    let mut rows: Vec<(Vec<f64>, f64, Vec<f64>, usize)> = Vec::new();
    let mut duplicates = 0;
    for i in 0..prob.m() {
        let gi: Vec<f64> = prob.g.row(i).iter().copied().collect();
        let nrm = gi.iter().map(|v| v * v).sum::<f64>().sqrt();
        let ei: Vec<f64> = prob.e.row(i).iter().copied().collect();
        if nrm <= 1e-12 * gmax {
            // 0 <= W_i + E_i theta.
            let en = ei.iter().map(|v| v * v).sum::<f64>().sqrt();
            if en <= 1e-12 {
                if prob.w[i] < -1e-12 * scale {
                    return Err(EmpcError::EmptyFeasibleSet);
                }
                continue;
            }
            prow.push((ei.iter().map(|v| -v / en).collect(), prob.w[i] / en));
            continue;
        }
        let gn: Vec<f64> = gi.iter().map(|v| v / nrm).collect();
        let en: Vec<f64> = ei.iter().map(|v| v / nrm).collect();
        let wn = prob.w[i] / nrm;
        let tol = 1e-10;
        let dup = rows.iter().any(|(g2, w2, e2, _)| {
            g2.iter().zip(&gn).all(|(a, b)| (a - b).abs() <= tol)
                && (w2 - wn).abs() <= tol * scale
                && e2.iter().zip(&en).all(|(a, b)| (a - b).abs() <= tol)
        });
        if dup {
            duplicates += 1;
            continue;
        }
        rows.push((gn, wn, en, i));
    }
    let m = rows.len();
    let mut g = DMatrix::zeros(m, n);
    let mut w = DVector::zeros(m);
    let mut e = DMatrix::zeros(m, p);
    let mut kept = Vec::with_capacity(m);
    for (r, (gi, wi, ei, orig)) in rows.into_iter().enumerate() {
        for j in 0..n {
            g[(r, j)] = gi[j];
        }
        for j in 0..p {
            e[(r, j)] = ei[j];
        }
        w[r] = wi;
        kept.push(orig);
    }
    let mut param_a = DMatrix::zeros(prow.len(), p);
    let mut param_b = DVector::zeros(prow.len());
    for (r, (a, b)) in prow.into_iter().enumerate() {
        for j in 0..p {
            param_a[(r, j)] = a[j];
        }
        param_b[r] = b;
    }
    let hinv_gt = &hinv * g.transpose();
    let hinv_ft = &hinv * prob.f_theta.transpose();
    let hinv_f = &hinv * &prob.f;
    Ok(Prepared {
        n,
        p,
        m,
        h: prob.h.clone(),
        hinv,
        ft: prob.f_theta.clone(),
        f: prob.f.clone(),
        g,
        w,
        e,
        kept,
        param_a,
        param_b,
        hinv_gt,
        hinv_ft,
        hinv_f,
        scale,
        radius_tol: settings.radius_tol * scale,
        duplicates,
        theta_lb: prob.theta_lb.clone(),
        theta_ub: prob.theta_ub.clone(),
    })
}
