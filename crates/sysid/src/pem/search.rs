//! The Levenberg-Marquardt search of [`pem`].

use super::criterion::{Objective, ResidualWeights};
use super::layout::Layout;
use super::limits::check_size;
use super::normal::normal_equations;
use super::residuals::{
    multistep_count, multistep_residuals, residuals, stack_residuals, without_k,
};
use super::result::PemResult;
use super::series::{Series, series_of};
use super::settings::{Criterion, Focus, PemSettings};
use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::spectral_radius;
use crate::lm::{LeastSquares, LmSettings, NormalEquations, levenberg_marquardt};
use crate::model::InnovationModel;
use crate::n4sid::{Scaling, stabilise_k};
use crate::validate::{estimate_x0_predictor, estimate_x0_simulation};
use core::convert::Infallible;
use nalgebra::{DMatrix, DVector};

/// Prediction-error identification of an innovation model (4.4)-(4.10):
/// minimises the mean squared one-step prediction error (of the outputs
/// scaled to unit variance) over `A, B, C, K`, optionally `D`, and one
/// initial state per experiment, starting from `start` (with
/// [`PemSettings::horizon`] `h > 1`: the mean squared error of the
/// `1..=h`-step-ahead predictions, a multi-step focus).
///
/// The search is Levenberg-Marquardt ([`crate::lm`], damping capped at
/// `1e12`) on the Gauss-Newton Hessian `J'J` with the exact Jacobian from forward sensitivity recursions of the
/// predictor (no finite differences). Every step is taken in data-driven
/// local coordinates: the `nx^2` directions that only change the state
/// basis are projected out, which makes the problem well posed. A trial
/// step that makes `A` or `A - KC` unstable (spectral radius above
/// `1 - stability_margin`, or for `A` above
/// [`PemSettings::max_radius_a`] when set) is rejected like one that
/// raises the cost.
/// With [`Focus::Simulation`] `K` is fixed at zero, so the criterion is
/// the simulation error.
///
/// A search whose Jacobian would exceed
/// [`MAX_PEM_JACOBIAN_BYTES`](crate::MAX_PEM_JACOBIAN_BYTES) or whose
/// iterations would exceed
/// [`MAX_PEM_FLOPS_PER_ITERATION`](crate::MAX_PEM_FLOPS_PER_ITERATION)
/// (a long [`PemSettings::horizon`], a high order) is refused with
/// [`SysidError::TooLarge`] before it starts.
///
/// ```
/// use kestrel_sysid::{n4sid, pem, synthetic, N4sidSettings, PemSettings};
/// let truth = synthetic::random_model(2, 1, 1, 3, 0.8);
/// let data = synthetic::simulate(&truth, 1000, 0.1, 1).unwrap();
/// let start = n4sid(&data, &N4sidSettings { order: Some(2), ..Default::default() }).unwrap();
/// let r = pem(&data, &start.model, &PemSettings::default()).unwrap();
/// assert!(r.cost <= r.initial_cost);
/// assert!(r.model.radius_a() < 1.0 && r.model.radius_predictor() < 1.0);
/// ```
pub fn pem(data: &IoData, start: &InnovationModel, settings: &PemSettings) -> Result<PemResult> {
    if start.nu() != data.nu() {
        return Err(SysidError::dim("start model inputs", data.nu(), start.nu()));
    }
    if start.ny() != data.ny() {
        return Err(SysidError::dim(
            "start model outputs",
            data.ny(),
            start.ny(),
        ));
    }
    start.validate()?;
    let scaling = Scaling::of(data)?;
    let sdata = data.scaled(&scaling.su, &scaling.sy);
    let (n, nu, ny) = (start.nx(), data.nu(), data.ny());
    let ne = data.experiments().len();
    let has_k = settings.focus == Focus::Prediction;
    if settings.fixed_dynamics && !has_k {
        return Err(SysidError::invalid(
            "fixed_dynamics estimates K only and needs the prediction focus",
        ));
    }
    let h = settings.horizon;
    if h == 0 || (h > 1 && !has_k) {
        return Err(SysidError::invalid(format!(
            "PEM horizon {h}: must be at least 1, and 1 with the simulation focus"
        )));
    }
    if let Some(bad) = settings.steps.iter().find(|&&k| k == 0 || k > h) {
        return Err(SysidError::invalid(format!(
            "PEM step {bad}: the selected steps must lie in 1..={h} (the horizon)"
        )));
    }
    let ws = settings.simulation_weight;
    if !ws.is_finite() || ws < 0.0 {
        return Err(SysidError::invalid(format!(
            "PEM simulation weight {ws}: must be finite and not negative"
        )));
    }
    let sim = ws > 0.0;
    if sim && (!has_k || settings.fixed_dynamics || settings.criterion == Criterion::Determinant) {
        return Err(SysidError::invalid(
            "a simulation term (simulation_weight > 0) needs the prediction focus, \
             estimated dynamics (not fixed_dynamics) and the trace or fit criterion",
        ));
    }
    let mut lay = Layout::new(n, nu, ny, ne, settings.feedthrough, has_k);
    if sim {
        lay = lay.with_simulation();
    }
    let shortest = data
        .experiments()
        .iter()
        .map(|e| e.len())
        .min()
        .unwrap_or(0);
    let m_total = data.n_samples() * ny;
    if m_total < 2 * lay.p || shortest < n + 1 {
        return Err(SysidError::TooFewSamples {
            what: format!("PEM with {} parameters (order {n})", lay.p),
            needed: (2 * lay.p).div_ceil(ny).max(n + 1),
            found: data.n_samples(),
        });
    }
    let n_residuals: usize = data
        .experiments()
        .iter()
        .map(|e| multistep_count(e.len(), h) * ny + if sim { e.len() * ny } else { 0 })
        .sum();
    check_size(n_residuals, lay.p, n, h)?;
    let limit = 1.0 - settings.stability_margin;
    let limit_a = match settings.max_radius_a {
        None => limit,
        Some(r) if !(r.is_finite() && r > 0.0) => {
            return Err(SysidError::invalid(format!(
                "PEM max_radius_a {r}: must be finite and positive"
            )));
        }
        Some(r) if r > limit && (!has_k || settings.fixed_dynamics || sim) => {
            return Err(SysidError::invalid(format!(
                "PEM max_radius_a {r} allows an unstable A: needs the prediction focus with \
                 estimated dynamics and no simulation term (only the predictor A - KC is \
                 then required to be stable)"
            )));
        }
        Some(r) => r,
    };
    let mut base = scaling.scale(start);
    if !has_k {
        base.k.fill(0.0);
    }
    if base.radius_a() > limit_a {
        return Err(SysidError::Unstable {
            what: "A of the start model".into(),
            radius: base.radius_a(),
            limit: limit_a,
        });
    }
    if has_k && base.radius_predictor() > limit {
        base.k = stabilise_k(&base.a, &base.c, base.k.clone());
    }
    let x0: Vec<DVector<f64>> = sdata
        .experiments()
        .iter()
        .map(|e| estimate_x0_predictor(&base, &e.u, &e.y))
        .collect::<Result<_>>()?;
    let xs0: Vec<DVector<f64>> = if sim {
        let m0 = without_k(&base);
        sdata
            .experiments()
            .iter()
            .map(|e| estimate_x0_simulation(&m0, &e.u, &e.y))
            .collect::<Result<_>>()?
    } else {
        Vec::new()
    };
    let series = series_of(&sdata);
    let objective = Objective::new(settings, &series, ny);
    let res_only = |m: &InnovationModel, x: &[DVector<f64>], xs: &[DVector<f64>]| {
        let mut r = if h > 1 {
            multistep_residuals(m, x, &series, h)
        } else {
            residuals(m, x, &series)
        };
        if sim {
            r = stack_residuals(r, &residuals(&without_k(m), xs, &series));
        }
        objective.mask(&mut r);
        r
    };
    let mut theta = lay.pack(&base, &x0);
    lay.pack_simulation(&mut theta, &xs0);
    let mut res = res_only(&base, &x0, &xs0);
    let mf = objective.count(res.len());
    let initial_cost = res.norm_squared() / mf;
    let w = objective.weights_at(&res);
    w.apply(&objective.groups, &mut res);
    let (hessian, gradient) =
        normal_equations(&lay, &base, (&x0, &xs0), &series, h, &objective, &w, &res);
    let first = NormalEquations {
        cost: res.norm_squared() / mf,
        hessian,
        gradient,
    };
    let mut problem = PemProblem {
        lay: &lay,
        base: &base,
        objective: &objective,
        series: &series,
        h,
        res_only: &res_only,
        last_trial: None,
        w,
        mf,
        limit,
        limit_a,
        has_k,
        reweigh: settings.criterion != Criterion::Trace,
        fixed_dynamics: settings.fixed_dynamics,
        first: Some(first),
    };
    let lm = LmSettings {
        max_iterations: settings.max_iterations,
        cost_tolerance: settings.cost_tolerance,
        gradient_tolerance: settings.gradient_tolerance,
        step_tolerance: settings.step_tolerance,
        gradient_divisor: mf,
        initial_damping: 1e-3,
        max_damping: 1e12,
        bounds: None,
    };
    let found = match levenberg_marquardt(&mut problem, theta, &lm) {
        Ok(found) => found,
        Err(never) => match never {},
    };
    theta = found.theta;
    let (model, x0s) = lay.unpack(&theta, &base);
    let xss = lay.simulation_x0(&theta);
    let final_res = res_only(&model, &x0s, &xss);
    // The prediction errors only (the simulation errors come last).
    let n_sim = if sim {
        series.iter().map(|s| s.n * ny).sum::<usize>()
    } else {
        0
    };
    let n_pred = final_res.len() - n_sim;
    let em = DMatrix::from_column_slice(ny, n_pred / ny, &final_res.as_slice()[..n_pred]);
    let det_cost = (&em * em.transpose() / (mf - n_sim as f64).max(1.0) * ny as f64).determinant();
    Ok(PemResult {
        model: scaling.unscale(&model),
        x0: x0s,
        simulation_x0: xss,
        initial_cost,
        cost: found.accepted.unwrap_or(initial_cost),
        det_cost,
        history: found.history,
        iterations: found.iterations,
        evaluations: found.evaluations,
        free_parameters: found.search_dimension,
        stop: found.stop,
    })
}

/// [`pem`] as a [`LeastSquares`] problem: the residuals weighed by the
/// criterion's weights (renewed at every linearisation unless the
/// criterion is the trace), trial points admissible when `A` and
/// `A - KC` are stable, the search in data-driven local coordinates.
struct PemProblem<'a, R> {
    lay: &'a Layout,
    base: &'a InnovationModel,
    objective: &'a Objective,
    series: &'a [Series],
    /// The prediction horizon.
    h: usize,
    /// The masked, unweighted residuals of a point.
    res_only: &'a R,
    /// The last trial point and its residuals (the search linearises
    /// there next when it accepts it).
    last_trial: Option<(DVector<f64>, DVector<f64>)>,
    w: ResidualWeights,
    mf: f64,
    limit: f64,
    /// Largest spectral radius of `A` ([`PemSettings::max_radius_a`]).
    limit_a: f64,
    has_k: bool,
    reweigh: bool,
    fixed_dynamics: bool,
    /// The normal equations at the start (computed before the search for
    /// the residual count).
    first: Option<NormalEquations>,
}

impl<R> LeastSquares for PemProblem<'_, R>
where
    R: Fn(&InnovationModel, &[DVector<f64>], &[DVector<f64>]) -> DVector<f64>,
{
    type Error = Infallible;
    /// The unweighted cost.
    type Trial = f64;

    fn linearise(
        &mut self,
        theta: &DVector<f64>,
    ) -> core::result::Result<NormalEquations, Infallible> {
        if let Some(first) = self.first.take() {
            return Ok(first);
        }
        let (model, x0s) = self.lay.unpack(theta, self.base);
        let xss = self.lay.simulation_x0(theta);
        let mut res = match self.last_trial.take() {
            Some((at, r)) if at == *theta => r,
            _ => (self.res_only)(&model, &x0s, &xss),
        };
        if self.reweigh {
            self.w = self.objective.weights_at(&res);
        }
        self.w.apply(&self.objective.groups, &mut res);
        let (hessian, gradient) = normal_equations(
            self.lay,
            &model,
            (&x0s, &xss),
            self.series,
            self.h,
            self.objective,
            &self.w,
            &res,
        );
        Ok(NormalEquations {
            cost: res.norm_squared() / self.mf,
            hessian,
            gradient,
        })
    }

    fn admissible(&mut self, theta: &DVector<f64>) -> bool {
        let (m, _) = self.lay.unpack(theta, self.base);
        spectral_radius(&m.a) <= self.limit_a
            && (!self.has_k || spectral_radius(&(&m.a - &m.k * &m.c)) <= self.limit)
    }

    fn trial(&mut self, theta: &DVector<f64>) -> Option<(f64, f64)> {
        let (m, x0) = self.lay.unpack(theta, self.base);
        let xs = self.lay.simulation_x0(theta);
        let mut r = (self.res_only)(&m, &x0, &xs);
        self.last_trial = Some((theta.clone(), r.clone()));
        let plain = r.norm_squared() / self.mf;
        self.w.apply(&self.objective.groups, &mut r);
        Some((r.norm_squared() / self.mf, plain))
    }

    fn basis(&mut self, theta: &DVector<f64>) -> Option<DMatrix<f64>> {
        let lay = self.lay;
        Some(if self.fixed_dynamics {
            // Only K and the initial states move: no similarity freedom left.
            let idx: Vec<usize> = (lay.ok..lay.p).collect();
            DMatrix::from_fn(lay.p, idx.len(), |r, c| if r == idx[c] { 1.0 } else { 0.0 })
        } else {
            let (model, x0s) = lay.unpack(theta, self.base);
            lay.ddlc(&model, &x0s, &lay.simulation_x0(theta))
        })
    }
}
