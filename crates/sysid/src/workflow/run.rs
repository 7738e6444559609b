//! The workflow itself: [`identify`].

use super::report::{IdentifyReport, N4sidSummary, PemSummary, ReductionSummary};
use super::segment::select_segments;
use super::spec::{AfterReduction, IdentifySpec, Method, PemFocus};
use crate::data::{IoData, Offsets, SignalSelection};
use crate::error::{Result, SysidError};
use crate::filter::Butterworth;
use crate::n4sid::{N4sidSettings, n4sid};
use crate::pem::{Focus, PemResult, PemSettings, pem};
use crate::reduce::{BalredSettings, ReductionMethod, balred, transmission_zeros};
use crate::validate::validate;
use nalgebra::DVector;

fn offset_vec(
    v: &Option<Vec<f64>>,
    n: usize,
    default: &DVector<f64>,
    what: &str,
) -> Result<DVector<f64>> {
    match v {
        Some(v) if v.len() != n => Err(SysidError::dim(what, n, v.len())),
        Some(v) => Ok(DVector::from_vec(v.clone())),
        None => Ok(default.clone()),
    }
}

/// Runs the identification workflow on `data` (as loaded, e.g. by
/// [`IoData::read_csv`]): input map, interval selection, operating point,
/// low-pass, N4SID, PEM, `balred`, zeros and the validation table.
///
/// ```
/// use kestrel_sysid::{synthetic, workflow::{identify, IdentifySpec, Segment}};
/// let truth = synthetic::random_model(2, 2, 1, 9, 0.9);
/// let data = synthetic::simulate(&truth, 1200, 0.05, 3).unwrap();
/// let spec = IdentifySpec {
///     estimate: Segment::parse_list("0:799").unwrap(),
///     validate: Segment::parse_list("1@800:1199").unwrap(),
///     order: Some(2),
///     ..Default::default()
/// };
/// let report = identify(&data, &spec).unwrap();
/// assert!(report.validation.row("model 1-step").unwrap().mean() > 80.0);
/// println!("{report}");
/// ```
pub fn identify(data: &IoData, spec: &IdentifySpec) -> Result<IdentifyReport> {
    let raw_nu = data.nu();
    let data = match &spec.input_map {
        Some(m) => data.map_inputs(&m.matrix, m.names.clone())?,
        None => data.clone(),
    };
    let est = if spec.estimate.is_empty() {
        data.clone()
    } else {
        select_segments(&data, &spec.estimate)?
    };
    let val = if spec.validate.is_empty() {
        None
    } else {
        Some(select_segments(&data, &spec.validate)?)
    };
    let means = est.means();
    let u0 = match (&spec.input_map, &spec.u0) {
        (Some(m), Some(_)) => &m.matrix * offset_vec(&spec.u0, raw_nu, &means.u0, "u0")?,
        _ => offset_vec(&spec.u0, est.nu(), &means.u0, "u0")?,
    };
    let y0 = offset_vec(&spec.y0, est.ny(), &means.y0, "y0")?;
    let offsets = Offsets { u0, y0 };
    let mut est = est.subtract(&offsets)?;
    let mut val = val.map(|v| v.subtract(&offsets)).transpose()?;
    if let Some(lp) = spec.lowpass {
        let f = Butterworth::design(lp.order, lp.cutoff, data.ts())?;
        est = est.lowpass(&f, SignalSelection::Both);
        val = val.map(|v| v.lowpass(&f, SignalSelection::Both));
    }
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
    let start = n4sid(&est, &n4)?;
    let n4sid_summary = N4sidSummary {
        order: start.order,
        suggested_order: start.suggested_order,
        horizon: start.horizon,
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
        criterion: spec.criterion,
        ..Default::default()
    };
    let noise = PemSettings {
        focus: Focus::Prediction,
        fixed_dynamics: true,
        feedthrough: false,
        horizon: spec.pem_horizon,
        ..settings.clone()
    };
    let (full_model, pem_summary, pem_noise) = match spec.method {
        Method::N4sid => (start.model, None, None),
        Method::Pem => {
            let r = pem(&est, &start.model, &settings)?;
            if spec.focus.refits_noise() {
                let r2 = pem(&est, &r.model, &noise)?;
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
            let r = pem(&est, &model, &noise)?;
            (r.model.clone(), Some(summary(&r)))
        }
        (Method::Pem, Some(_), AfterReduction::All) => {
            let all = PemSettings {
                feedthrough: spec.feedthrough || model.d.amax() > 0.0,
                ..settings.clone()
            };
            let r = pem(&est, &model, &all)?;
            if spec.focus.refits_noise() {
                let r2 = pem(&est, &r.model, &noise)?;
                (r2.model.clone(), Some(summary(&r2)))
            } else {
                (r.model.clone(), Some(summary(&r)))
            }
        }
        _ => (model, None),
    };
    let zeros = transmission_zeros(&model).map_err(|e| e.to_string());
    let vdata = val.as_ref().unwrap_or(&est);
    let validation = validate(&model, vdata, &spec.horizons)?;
    let full_validation = if reduction.is_some() {
        Some(validate(&full_model, vdata, &spec.horizons)?)
    } else {
        None
    };
    Ok(IdentifyReport {
        estimation_samples: est.n_samples(),
        experiments: est.experiments().len(),
        ts: est.ts(),
        offsets,
        input_names: est.input_names().to_vec(),
        output_names: est.output_names().to_vec(),
        n4sid: n4sid_summary,
        pem: pem_summary,
        pem_noise,
        pem_reduced,
        full_model,
        reduction,
        model,
        zeros,
        on_validation_data: val.is_some(),
        validation,
        full_validation,
    })
}
