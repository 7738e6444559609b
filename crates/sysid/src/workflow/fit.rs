//! N4SID, PEM and `balred` of a spec on prepared data: the part of the
//! workflow that the structure choice repeats on every fold.

use super::report::{N4sidSummary, PemSummary, ReductionSummary};
use super::spec::{ARX_LAGS, AfterReduction, IdentifySpec, Method, PemFocus, Start};
use crate::closed_loop::{ArxReductionSettings, PbsidSettings, arx_reduction, pbsid};
use crate::data::IoData;
use crate::error::Result;
use crate::model::InnovationModel;
use crate::n4sid::{N4sidSettings, n4sid};
use crate::pem::{Focus, PemResult, PemSettings, pem};
use crate::reduce::{BalredSettings, ReductionMethod, balred};

/// What [`fit_structure`] produced on one data set.
pub(super) struct Fitted {
    /// The N4SID step.
    pub n4sid: N4sidSummary,
    /// The PEM step.
    pub pem: Option<PemSummary>,
    /// The noise-model stage.
    pub pem_noise: Option<PemSummary>,
    /// The refit after the reduction.
    pub pem_reduced: Option<PemSummary>,
    /// The model of the identified order.
    pub full_model: InnovationModel,
    /// The reduction step.
    pub reduction: Option<ReductionSummary>,
    /// The final model.
    pub model: InnovationModel,
}

/// N4SID, PEM and `balred` of `spec` on the prepared (mean-free,
/// filtered) estimation data `est`: the part of the workflow that the
/// structure choice repeats on every fold.
/// `max_radius_a`: [`PemSettings::max_radius_a`] of the first PEM stage.
pub(super) fn fit_structure(
    est: &IoData,
    spec: &IdentifySpec,
    max_radius_a: Option<f64>,
) -> Result<Fitted> {
    let n4 = N4sidSettings {
        order: spec.order,
        max_order: spec.order.unwrap_or(10).max(10),
        horizon: spec.horizon,
        past_horizon: None,
        weighting: spec.weighting,
        feedthrough: spec.feedthrough,
        estimate_k: true,
        matrices: spec.n4sid_matrices,
    };
    // (model, order, suggested order, horizon) of the start.
    let (start_model, order, suggested_order, horizon) = match spec.start {
        Start::N4sid => {
            let r = n4sid(est, &n4)?;
            (r.model, r.order, r.suggested_order, r.horizon)
        }
        Start::Pbsid => {
            let settings = PbsidSettings {
                order: spec.order,
                max_order: n4.max_order,
                past: spec.horizon,
                feedthrough: spec.feedthrough,
                ..Default::default()
            };
            let r = pbsid(est, &settings)?;
            (r.model, r.order, r.suggested_order, r.past)
        }
        Start::Arx | Start::Armax => {
            let lags = spec.horizon.unwrap_or(ARX_LAGS);
            let settings = ArxReductionSettings {
                order: spec.order,
                max_order: n4.max_order,
                lags,
                noise_lags: if spec.start == Start::Armax { lags } else { 0 },
                feedthrough: spec.feedthrough,
                ..Default::default()
            };
            let r = arx_reduction(est, &settings)?;
            (r.model, r.order, r.suggested_order, r.lags)
        }
    };
    let n4sid_summary = N4sidSummary {
        order,
        suggested_order,
        horizon,
        start: spec.start,
    };
    let summary = |r: &PemResult| PemSummary {
        iterations: r.iterations,
        free_parameters: r.free_parameters,
        initial_cost: r.initial_cost,
        cost: r.cost,
        stop: r.stop,
    };
    let settings = PemSettings {
        focus: match spec.focus {
            PemFocus::Prediction | PemFocus::MultiStepThenNoise { .. } => Focus::Prediction,
            PemFocus::Simulation | PemFocus::SimulationThenNoise => Focus::Simulation,
        },
        feedthrough: spec.feedthrough,
        max_iterations: spec.max_iterations,
        horizon: match spec.focus {
            PemFocus::Prediction => spec.pem_horizon,
            PemFocus::MultiStepThenNoise { horizon } => horizon,
            PemFocus::Simulation | PemFocus::SimulationThenNoise => 1,
        },
        steps: match spec.focus {
            PemFocus::Prediction => spec.pem_steps.clone(),
            PemFocus::MultiStepThenNoise { .. }
            | PemFocus::Simulation
            | PemFocus::SimulationThenNoise => Vec::new(),
        },
        criterion: spec.criterion,
        max_radius_a,
        ..Default::default()
    };
    let noise = PemSettings {
        focus: Focus::Prediction,
        fixed_dynamics: true,
        feedthrough: false,
        max_radius_a: None,
        horizon: spec.pem_horizon,
        steps: spec.pem_steps.clone(),
        ..settings.clone()
    };
    let (full_model, pem_summary, pem_noise) = match spec.method {
        Method::N4sid => (start_model, None, None),
        Method::Pem => {
            let r = pem(est, &start_model, &settings)?;
            if spec.focus.refits_noise() {
                let r2 = pem(est, &r.model, &noise)?;
                (r2.model.clone(), Some(summary(&r)), Some(summary(&r2)))
            } else {
                (r.model.clone(), Some(summary(&r)), None)
            }
        }
    };
    let (model, reduction) = match spec.reduce {
        Some(r) => {
            let red = balred(
                &full_model,
                r,
                &BalredSettings {
                    method: if spec.match_dc {
                        ReductionMethod::MatchDc
                    } else {
                        ReductionMethod::Truncate
                    },
                    include_noise: true,
                },
            )?;
            let s = ReductionSummary {
                from: full_model.nx(),
                to: r,
                hankel_singular_values: red.hankel_singular_values,
                error_bound: red.error_bound,
            };
            (red.model, Some(s))
        }
        None => (full_model.clone(), None),
    };
    let (model, pem_reduced) = match (spec.method, &reduction, spec.after_reduction) {
        (Method::Pem, Some(_), AfterReduction::NoiseModel) => {
            let r = pem(est, &model, &noise)?;
            (r.model.clone(), Some(summary(&r)))
        }
        (Method::Pem, Some(_), AfterReduction::All) => {
            let all = PemSettings {
                feedthrough: spec.feedthrough || model.d.amax() > 0.0,
                ..settings.clone()
            };
            let r = pem(est, &model, &all)?;
            if spec.focus.refits_noise() {
                let r2 = pem(est, &r.model, &noise)?;
                (r2.model.clone(), Some(summary(&r2)))
            } else {
                (r.model.clone(), Some(summary(&r)))
            }
        }
        _ => (model, None),
    };
    Ok(Fitted {
        n4sid: n4sid_summary,
        pem: pem_summary,
        pem_noise,
        pem_reduced,
        full_model,
        reduction,
        model,
    })
}
