//! The Levenberg-Marquardt search of one stage and the standard errors.

use crate::ident::greybox::problem::{Eval, Gain, Problem};
use crate::ident::greybox::report::{Stage, StageSummary};
use kestrel_sysid::linalg::{pinv, spectral_radius};
use kestrel_sysid::{Result, StopReason, SysidError};
use kestrel_tricopter_model::GreyBoxParams;
use nalgebra::{DMatrix, DVector};

/// Runs one stage from the parameters `g`, gain `k0` (for a free gain)
/// and initial states `x0`.
pub(super) fn run_stage(
    prob: &mut Problem,
    stage: Stage,
    g: &GreyBoxParams,
    k0: Option<DMatrix<f64>>,
    x0: &[DVector<f64>],
) -> Result<Search> {
    let (nx, ny) = (prob.nx, prob.ny);
    prob.gain = match stage {
        Stage::EquationError => Gain::Reset,
        Stage::Simulation => Gain::Fixed(DMatrix::zeros(nx, ny)),
        Stage::Prediction | Stage::Noise => Gain::Free,
    };
    prob.g_fixed = *g;
    let mut theta = DVector::zeros(prob.n_params());
    let ga = g.to_array();
    for (k, &i) in prob.phys.iter().enumerate() {
        theta[k] = ga[i].ln();
    }
    if let (true, Some(k0)) = (prob.k_free(), k0) {
        for i in 0..nx {
            for j in 0..ny {
                theta[prob.off_k() + i * ny + j] = k0[(i, j)];
            }
        }
    }
    for (ei, x) in x0.iter().enumerate() {
        let o = prob.off_x0() + ei * nx;
        theta.rows_mut(o, nx).copy_from(x);
    }
    levenberg_marquardt(prob, theta)
}

/// Outcome of one Levenberg-Marquardt run.
pub(super) struct Search {
    pub(super) theta: DVector<f64>,
    pub(super) eval: Eval,
    pub(super) initial_cost: f64,
    pub(super) cost: f64,
    pub(super) iterations: usize,
    pub(super) stop: StopReason,
}

impl Search {
    pub(super) fn summary(&self, stage: Stage) -> StageSummary {
        StageSummary {
            stage,
            iterations: self.iterations,
            initial_cost: self.initial_cost,
            cost: self.cost,
            stop: self.stop,
        }
    }
}

pub(super) fn cost_of(e: &Eval) -> f64 {
    e.r.norm_squared()
}

pub(super) fn levenberg_marquardt(prob: &Problem, theta0: DVector<f64>) -> Result<Search> {
    let set = &prob.spec.settings;
    let mut theta = theta0;
    let mut eval = prob.evaluate(&theta, true)?;
    let initial_cost = cost_of(&eval);
    let mut cost = initial_cost;
    let mut mu = 1e-3;
    let mut iterations = 0;
    let mut stop = StopReason::MaxIterations;
    // A free gain keeps the predictor stable (it starts from K = A C',
    // whose predictor poles are the actuators').
    let limit = 1.0 - 1e-6;
    let nphys = prob.phys.len();
    while iterations < set.max_iterations {
        iterations += 1;
        let jac = eval.jac.as_ref().ok_or_else(|| {
            SysidError::Numerical("internal: Jacobian missing in the grey-box search".into())
        })?;
        let h = jac.transpose() * jac;
        let mut h = h;
        let mut g = jac.transpose() * &eval.r;
        // Active bounds: a log parameter on its bound whose descent
        // direction points outward is held (projected Levenberg-Marquardt).
        for k in 0..nphys {
            let at_hi = theta[k] >= prob.hi[k] && g[k] < 0.0;
            let at_lo = theta[k] <= prob.lo[k] && g[k] > 0.0;
            if at_hi || at_lo {
                g[k] = 0.0;
                h.row_mut(k).fill(0.0);
                h.column_mut(k).fill(0.0);
                h[(k, k)] = 1.0;
            }
        }
        if g.amax() <= set.gradient_tolerance * cost.max(f64::MIN_POSITIVE) {
            stop = StopReason::GradientTolerance;
            break;
        }
        let np = theta.len();
        let hmax = h.diagonal().amax();
        let dscale: Vec<f64> = (0..np)
            .map(|i| h[(i, i)].max(1e-12 * hmax).max(1e-300))
            .collect();
        let mut accepted = None;
        while mu < 1e14 {
            let mut lhs = h.clone();
            for i in 0..np {
                lhs[(i, i)] += mu * dscale[i];
            }
            let Some(ch) = lhs.cholesky() else {
                mu *= 10.0;
                continue;
            };
            let step = ch.solve(&(-&g));
            let mut trial = &theta + &step;
            // Bounds: clamp the log parameters.
            for k in 0..nphys {
                trial[k] = trial[k].clamp(prob.lo[k], prob.hi[k]);
            }
            let ok = match prob.evaluate(&trial, false) {
                Ok(e)
                    if prob.k_free()
                        && spectral_radius(&(&e.model.a - &e.model.k * &e.model.c)) > limit =>
                {
                    None
                }
                Ok(e) => Some(e),
                // No hover trim, invalid parameter, divergence: reject.
                Err(_) => None,
            };
            if let Some(e) = ok {
                let c = cost_of(&e);
                if c < cost {
                    mu = (mu / 5.0).max(1e-12);
                    accepted = Some((trial, c));
                    break;
                }
            }
            mu *= 5.0;
        }
        let Some((trial, c_new)) = accepted else {
            stop = StopReason::NoProgress;
            break;
        };
        let rel = (cost - c_new) / cost;
        let step_norm = (&trial - &theta).norm();
        theta = trial;
        cost = c_new;
        eval = prob.evaluate(&theta, true)?;
        if rel < set.cost_tolerance {
            stop = StopReason::CostTolerance;
            break;
        }
        if step_norm < set.step_tolerance * (1.0 + theta.norm()) {
            stop = StopReason::StepTolerance;
            break;
        }
    }
    Ok(Search {
        theta,
        eval,
        initial_cost,
        cost,
        iterations,
        stop,
    })
}

/// Standard errors of the free log parameters (in `prob.phys` order):
/// `cov = (Ψ' Σ^-1 Ψ)^-1` with `Σ` the per-output residual variance.
pub(super) fn standard_errors(prob: &Problem, eval: &Eval) -> Option<Vec<f64>> {
    let jac = eval.jac.as_ref()?;
    let ny = prob.ny;
    let m = prob.m_total;
    let norm = (m as f64).sqrt();
    // Unscaled residual variance per output.
    let mut var = vec![0.0; ny];
    for (row, v) in eval.r.iter().enumerate() {
        let j = row % ny;
        var[j] += (v * prob.sy[j] * norm).powi(2);
    }
    let n = (m / ny) as f64;
    for v in &mut var {
        *v /= n;
    }
    // Rows weighed: de/dθ / sigma_j = dr/dθ * s_j * norm / sigma_j.
    let mut w = jac.clone();
    for row in 0..m {
        let j = row % ny;
        let f = prob.sy[j] * norm / var[j].sqrt().max(f64::MIN_POSITIVE);
        w.row_mut(row).scale_mut(f);
    }
    let info = w.transpose() * w;
    // Jacobi scaling before the factorisations: the information of
    // log parameters, gains and initial states differs by many decades.
    let d: Vec<f64> = (0..info.nrows())
        .map(|i| 1.0 / info[(i, i)].max(f64::MIN_POSITIVE).sqrt())
        .collect();
    let scaled = DMatrix::from_fn(info.nrows(), info.ncols(), |i, j| {
        info[(i, j)] * d[i] * d[j]
    });
    // Marginal covariance of the physical parameters: the Schur complement
    // of the nuisance block (gain, initial states; pseudo-inverted, since
    // an initial state of a mode the data hardly see is nearly free).
    let p = prob.phys.len();
    let q = scaled.nrows() - p;
    let ipp = scaled.view((0, 0), (p, p));
    let ipn = scaled.view((0, p), (p, q));
    let inn = scaled.view((p, p), (q, q)).into_owned();
    let schur = ipp - ipn * pinv(&inn) * ipn.transpose();
    let cov = schur.cholesky()?.inverse();
    (0..p)
        .map(|k| {
            let v = cov[(k, k)] * d[k] * d[k];
            (v.is_finite() && v >= 0.0).then(|| v.sqrt())
        })
        .collect()
}
