//! The Levenberg-Marquardt loop.

use super::problem::{LeastSquares, NormalEquations};
use super::settings::LmSettings;
use nalgebra::DVector;

/// Why the search stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The relative cost decrease fell below `cost_tolerance`.
    CostTolerance,
    /// The gradient fell below `gradient_tolerance`.
    GradientTolerance,
    /// The step fell below `step_tolerance`.
    StepTolerance,
    /// `max_iterations` reached.
    MaxIterations,
    /// No step lowering the cost (while keeping stability) was found even
    /// with very large damping: a local minimum within numerical precision.
    NoProgress,
}

/// Result of [`levenberg_marquardt`].
#[derive(Clone, Debug, PartialEq)]
pub struct LmResult<T> {
    /// The parameters at the end.
    pub theta: DVector<f64>,
    /// The cost at the start.
    pub initial_cost: f64,
    /// The cost at the end.
    pub cost: f64,
    /// The cost at the start and after every accepted step (the cost of
    /// the trial; a problem whose weights change at every linearisation
    /// reports there the cost with the new weights).
    pub history: Vec<f64>,
    /// Iterations done.
    pub iterations: usize,
    /// Linearisations and trial points (including rejected and
    /// inadmissible ones).
    pub evaluations: usize,
    /// Dimension of the last iteration's search space (the columns of
    /// the [`basis`](LeastSquares::basis), or the parameter count); 0
    /// without iterations.
    pub search_dimension: usize,
    /// What the last accepted trial gave besides its cost (`None`: no
    /// step was accepted).
    pub accepted: Option<T>,
    /// Whether the problem's last [`linearise`](LeastSquares::linearise)
    /// was at [`LmResult::theta`] (not so after a stop on the cost or
    /// step tolerance).
    pub linearised: bool,
    /// Why the search stopped.
    pub stop: StopReason,
}

/// Minimises a [`LeastSquares`] problem from `theta0`: see the
/// [module docs](super).
pub fn levenberg_marquardt<P: LeastSquares>(
    problem: &mut P,
    theta0: DVector<f64>,
    settings: &LmSettings,
) -> Result<LmResult<P::Trial>, P::Error> {
    let mut theta = theta0;
    let NormalEquations {
        cost,
        hessian: mut h,
        gradient: mut g,
    } = problem.linearise(&theta)?;
    let initial_cost = cost;
    let mut cost = cost;
    let mut history = vec![cost];
    let mut mu = settings.initial_damping;
    let mut iterations = 0;
    let mut evaluations = 1;
    let mut search_dimension = 0;
    let mut last = None;
    let mut linearised = true;
    let mut stop = StopReason::MaxIterations;
    let bounds = settings.bounds.as_ref();
    while iterations < settings.max_iterations {
        iterations += 1;
        if let Some(b) = bounds {
            // Active bounds: held (projected Levenberg-Marquardt).
            for k in 0..b.lower.len() {
                let at_hi = theta[k] >= b.upper[k] && g[k] < 0.0;
                let at_lo = theta[k] <= b.lower[k] && g[k] > 0.0;
                if at_hi || at_lo {
                    g[k] = 0.0;
                    h.row_mut(k).fill(0.0);
                    h.column_mut(k).fill(0.0);
                    h[(k, k)] = 1.0;
                }
            }
        }
        let q = problem.basis(&theta);
        let (hr, gr) = match &q {
            Some(q) => (q.transpose() * &h * q, q.transpose() * &g),
            None => (h, g),
        };
        let n = hr.nrows();
        search_dimension = n;
        if gr.amax() / settings.gradient_divisor
            <= settings.gradient_tolerance * cost.max(f64::MIN_POSITIVE)
        {
            stop = StopReason::GradientTolerance;
            break;
        }
        let hmax = hr.diagonal().amax();
        let dscale: Vec<f64> = (0..n)
            .map(|i| hr[(i, i)].max(1e-12 * hmax).max(1e-300))
            .collect();
        let mut accepted = None;
        while mu < settings.max_damping {
            let mut lhs = hr.clone();
            for i in 0..n {
                lhs[(i, i)] += mu * dscale[i];
            }
            let Some(ch) = lhs.cholesky() else {
                mu *= 10.0;
                continue;
            };
            let d = ch.solve(&(-&gr));
            let step = match &q {
                Some(q) => q * d,
                None => d,
            };
            let mut trial = &theta + &step;
            if let Some(b) = bounds {
                for k in 0..b.lower.len() {
                    trial[k] = trial[k].clamp(b.lower[k], b.upper[k]);
                }
            }
            evaluations += 1;
            let outcome = if problem.admissible(&trial) {
                problem.trial(&trial)
            } else {
                None
            };
            if let Some((c, t)) = outcome
                && c.is_finite()
                && c < cost
            {
                mu = (mu / 5.0).max(1e-12);
                let length = if bounds.is_some() {
                    (&trial - &theta).norm()
                } else {
                    step.norm()
                };
                accepted = Some((trial, length, c, t));
                break;
            }
            mu *= 5.0;
        }
        let Some((trial, length, c_new, t)) = accepted else {
            stop = StopReason::NoProgress;
            break;
        };
        let rel = (cost - c_new) / cost;
        theta = trial;
        cost = c_new;
        history.push(cost);
        last = Some(t);
        if rel < settings.cost_tolerance {
            stop = StopReason::CostTolerance;
            linearised = false;
            break;
        }
        if length < settings.step_tolerance * (1.0 + theta.norm()) {
            stop = StopReason::StepTolerance;
            linearised = false;
            break;
        }
        let ne = problem.linearise(&theta)?;
        evaluations += 1;
        cost = ne.cost;
        h = ne.hessian;
        g = ne.gradient;
    }
    Ok(LmResult {
        theta,
        initial_cost,
        cost,
        history,
        iterations,
        evaluations,
        search_dimension,
        accepted: last,
        linearised,
        stop,
    })
}
