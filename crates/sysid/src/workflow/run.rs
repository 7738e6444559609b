//! The workflow itself: [`identify`].

use super::fit::{Fitted, fit_structure};
use super::prefilter::{Prefilter, choose_prefilter};
use super::report::IdentifyReport;
use super::segment::select_segments;
use super::select::{Progress, capped_iterations, choose_structure, spec_iteration_work};
use super::spec::IdentifySpec;
use crate::data::{IoData, Offsets, SignalSelection};
use crate::error::{Result, SysidError};
use crate::filter::Butterworth;
use crate::reduce::transmission_zeros;
use crate::validate::{Horizon, ValidationReport, validate};
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

/// Lowest simulation fit a report shows, percent: a model whose `A` has
/// modes beyond the unit circle (the prediction focus with
/// `max_radius_a` above 1) has a diverging simulation whose fit runs to
/// minus infinity; the table shows it as this value.
pub const SIMULATION_FIT_FLOOR: f64 = -9999.99;

/// Clips the simulation rows of `report` at [`SIMULATION_FIT_FLOOR`]
/// (non-finite values included).
fn clip_simulation(report: &mut ValidationReport) {
    for row in report
        .rows
        .iter_mut()
        .filter(|r| r.horizon == Horizon::Simulation)
    {
        for v in row.fit.iter_mut() {
            if v.is_nan() || *v < SIMULATION_FIT_FLOOR {
                *v = SIMULATION_FIT_FLOOR;
            }
        }
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
    identify_with_progress(data, spec, &|_| {})
}

/// [`identify`] that calls `progress` after every fit of the structure
/// choice (from the worker threads).
pub fn identify_with_progress(
    data: &IoData,
    spec: &IdentifySpec,
    progress: &(dyn Fn(&Progress) + Sync),
) -> Result<IdentifyReport> {
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
    let prefilter = match (spec.prefilter, spec.lowpass) {
        (Prefilter::Auto, None) => choose_prefilter(&est),
        (Prefilter::Auto, Some(_)) | (Prefilter::None, _) => None,
    };
    if let Some(cutoff) = prefilter.and_then(|p| p.cutoff) {
        let f = Butterworth::design(2, cutoff, data.ts())?;
        est = est.lowpass(&f, SignalSelection::Both);
        val = val.map(|v| v.lowpass(&f, SignalSelection::Both));
    }
    if let Some(lp) = spec.lowpass {
        let f = Butterworth::design(lp.order, lp.cutoff, data.ts())?;
        est = est.lowpass(&f, SignalSelection::Both);
        val = val.map(|v| v.lowpass(&f, SignalSelection::Both));
    }
    let (spec_for_fit, selection) = match &spec.auto {
        Some(auto) => match choose_structure(&est, spec, auto, progress) {
            Ok((mut s, r)) => {
                // The final fit's iterations bounded by the same work
                // estimate as the folds' (AutoSelect::final_work).
                // (A candidate run to convergence keeps its own count.)
                if r.chosen.iterations.is_none() {
                    let per = spec_iteration_work(
                        &s,
                        est.n_samples(),
                        est.nu(),
                        est.ny(),
                        auto.max_order,
                    );
                    s.max_iterations = capped_iterations(
                        auto.final_work,
                        per,
                        auto.min_iterations,
                        s.max_iterations,
                    );
                }
                (s, Some(Ok(r)))
            }
            // Too short a record for the folds: the spec as given.
            Err(e @ SysidError::TooFewSamples { .. }) => (spec.clone(), Some(Err(e.to_string()))),
            Err(e) => return Err(e),
        },
        None => (spec.clone(), None),
    };
    let spec = &spec_for_fit;
    let radius = match &selection {
        Some(Ok(r)) => r.chosen.max_radius_a,
        Some(Err(_)) | None => None,
    };
    let Fitted {
        n4sid: n4sid_summary,
        pem: pem_summary,
        pem_noise,
        pem_reduced,
        full_model,
        reduction,
        model,
    } = fit_structure(&est, spec, radius)?;
    let zeros = transmission_zeros(&model).map_err(|e| e.to_string());
    let vdata = val.as_ref().unwrap_or(&est);
    let mut validation = validate(&model, vdata, &spec.horizons)?;
    let mut full_validation = if reduction.is_some() {
        Some(validate(&full_model, vdata, &spec.horizons)?)
    } else {
        None
    };
    clip_simulation(&mut validation);
    if let Some(v) = full_validation.as_mut() {
        clip_simulation(v);
    }
    if let Some(lags) = &spec.arx_baseline {
        validation.add_arx_baseline(&est, vdata, lags.clone(), &spec.horizons)?;
        if let Some(v) = full_validation.as_mut() {
            v.add_arx_baseline(&est, vdata, lags.clone(), &spec.horizons)?;
        }
    }
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
        selection,
        prefilter,
    })
}
