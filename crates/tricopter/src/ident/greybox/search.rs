//! The Levenberg-Marquardt search of one stage and the standard errors.

use crate::ident::greybox::problem::{Eval, Gain, Problem};
use crate::ident::greybox::report::{Stage, StageSummary};
use core::cmp::Ordering;
use kestrel_sysid::linalg::{pinv, spectral_radius};
use kestrel_sysid::lm::{self, Bounds, LeastSquares, LmSettings, NormalEquations};
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

/// The search of one stage: [`kestrel_sysid::lm::levenberg_marquardt`]
/// with the log parameters clamped to their bounds (projected: a
/// parameter on its bound whose descent direction points outward is
/// held), a free gain's predictor kept stable, and a damping cap of
/// `1e14`.
pub(super) fn levenberg_marquardt(prob: &Problem, theta0: DVector<f64>) -> Result<Search> {
    let set = &prob.spec.settings;
    let lm = LmSettings {
        max_iterations: set.max_iterations,
        cost_tolerance: set.cost_tolerance,
        gradient_tolerance: set.gradient_tolerance,
        step_tolerance: set.step_tolerance,
        gradient_divisor: 1.0,
        initial_damping: 1e-3,
        max_damping: 1e14,
        bounds: Some(Bounds {
            lower: prob.lo.clone(),
            upper: prob.hi.clone(),
        }),
    };
    let mut ls = StageProblem {
        prob,
        // A free gain keeps the predictor stable (it starts from K = A C',
        // whose predictor poles are the actuators').
        limit: 1.0 - 1e-6,
        last: None,
    };
    let found = lm::levenberg_marquardt(&mut ls, theta0, &lm)?;
    let eval = match (found.linearised, ls.last) {
        (true, Some(eval)) => eval,
        _ => prob.evaluate(&found.theta, true)?,
    };
    Ok(Search {
        theta: found.theta,
        eval,
        initial_cost: found.initial_cost,
        cost: found.cost,
        iterations: found.iterations,
        stop: found.stop,
    })
}

/// One stage's search problem: the scaled residuals of [`Problem::evaluate`].
struct StageProblem<'p, 'a> {
    prob: &'p Problem<'a>,
    /// Largest spectral radius of `A - KC` with a free gain.
    limit: f64,
    /// The evaluation (with the Jacobian) of the last linearisation.
    last: Option<Eval>,
}

impl LeastSquares for StageProblem<'_, '_> {
    type Error = SysidError;
    type Trial = ();

    fn linearise(&mut self, theta: &DVector<f64>) -> Result<NormalEquations> {
        let eval = self.prob.evaluate(theta, true)?;
        let jac = eval.jac.as_ref().ok_or_else(|| {
            SysidError::Numerical("internal: Jacobian missing in the grey-box search".into())
        })?;
        let ne = NormalEquations {
            cost: cost_of(&eval),
            hessian: jac.transpose() * jac,
            gradient: jac.transpose() * &eval.r,
        };
        self.last = Some(eval);
        Ok(ne)
    }

    fn admissible(&mut self, theta: &DVector<f64>) -> bool {
        if !self.prob.k_free() {
            return true;
        }
        // No hover trim or an invalid parameter: rejected; so is an
        // unstable predictor (a NaN radius is left to the residuals).
        self.prob.model_of(theta).is_ok_and(|m| {
            let radius = spectral_radius(&(&m.a - &m.k * &m.c));
            radius.partial_cmp(&self.limit) != Some(Ordering::Greater)
        })
    }

    fn trial(&mut self, theta: &DVector<f64>) -> Option<(f64, ())> {
        // No hover trim, invalid parameter, divergence: rejected.
        let e = self.prob.evaluate(theta, false).ok()?;
        Some((cost_of(&e), ()))
    }
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
