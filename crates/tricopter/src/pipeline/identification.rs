//! Stage 3: the black-box and black-box virtual models of section 7.4
//! (kestrel-sysid's workflow with the thesis's set-up), their validation
//! and the data of figures 7.8-7.13.

use super::config::{Config, DataSets, Interval};
use super::error::{Context, PipelineError, Result};
use super::experiments::{Experiments, select};
use crate::ident::{ModelKind, thesis_spec};
use kestrel_core::formats::SsModel;
use kestrel_sysid::workflow::{PemSummary, Segment, identify, select_segments};
use kestrel_sysid::{
    IoData, TimeInterval, ValidationReport, Zero, estimate_x0_predictor, resid, transmission_zeros,
};
use nalgebra::{DMatrix, DVector};

/// Which model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelKey {
    /// Pulses in.
    BlackBox,
    /// Mixer inputs in.
    Virtual,
}

impl ModelKey {
    /// The key in file names and `summary.json` (`blackbox`, `virtual`).
    pub fn key(self) -> &'static str {
        match self {
            ModelKey::BlackBox => "blackbox",
            ModelKey::Virtual => "virtual",
        }
    }

    /// The thesis's name (`black-box`, `black-box virtual`).
    pub fn label(self) -> &'static str {
        match self {
            ModelKey::BlackBox => "black-box",
            ModelKey::Virtual => "black-box virtual",
        }
    }
}

/// Standard deviations of the measured rates of one data set.
#[derive(Clone, Debug, PartialEq)]
pub struct Excitation {
    /// Samples.
    pub samples: usize,
    /// Per output (rad/s).
    pub std: Vec<f64>,
}

/// The validation experiment of a figure: measured outputs against a
/// model's, as deviations from `y0`.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputComparison {
    /// Sample times (s).
    pub t: Vec<f64>,
    /// Measured outputs minus `y0` (samples x outputs).
    pub measured: DMatrix<f64>,
    /// The model's outputs minus `y0`.
    pub model: DMatrix<f64>,
    /// Fit per output (%), when computed for this comparison.
    pub fit: Option<Vec<f64>>,
}

/// One identified model.
#[derive(Clone, Debug)]
pub struct IdentifiedModel {
    /// Which.
    pub kind: ModelKey,
    /// Order before reduction.
    pub order: usize,
    /// Order after reduction.
    pub reduced_order: usize,
    /// The reduced model as `kestrel.ss.v1` (with `u0`/`y0`).
    pub ss: SsModel,
    /// The model before reduction.
    pub full_ss: SsModel,
    /// The removed output offsets.
    pub y0: DVector<f64>,
    /// Validation of the reduced model (fits and residual tests).
    pub validation: ValidationReport,
    /// Validation of the model before reduction.
    pub full_validation: ValidationReport,
    /// The PEM runs (simulation focus, then the noise model).
    pub pem: Vec<PemSummary>,
    /// Hankel singular values of the reduction.
    pub hankel_singular_values: Vec<f64>,
    /// Transmission zeros of the reduced model, or why they were not computed.
    pub zeros: std::result::Result<Vec<Zero>, String>,
    /// Excitation of the estimation data (the configured intervals).
    pub estimation: Excitation,
    /// Excitation of the validation data.
    pub validation_data: Excitation,
    /// Estimation samples the workflow used.
    pub estimation_samples: usize,
    /// Validation samples the workflow used.
    pub validation_samples: usize,
    /// Figure 7.8/7.9: simulation on the longest validation experiment.
    pub simulation: OutputComparison,
    /// Figure 7.10/7.11: 5-step prediction on it.
    pub five_step: OutputComparison,
}

impl IdentifiedModel {
    /// The fit row of the reduced model's validation (e.g. `model simulation`).
    pub fn fit(&self, row: &str) -> Option<Vec<f64>> {
        self.validation.row(row).map(|x| x.fit.clone())
    }
}

/// Stage 3's result.
#[derive(Clone, Debug)]
pub struct Identification {
    /// The black-box model (the MPC's design model).
    pub blackbox: IdentifiedModel,
    /// The black-box virtual model.
    pub virtual_: IdentifiedModel,
}

impl Identification {
    /// Both models, black-box first.
    pub fn models(&self) -> [&IdentifiedModel; 2] {
        [&self.blackbox, &self.virtual_]
    }
}

fn excitation(d: &IoData) -> Excitation {
    let n = d.n_samples() as f64;
    let std = (0..d.ny())
        .map(|j| {
            let m = d
                .experiments()
                .iter()
                .map(|e| e.y.column(j).sum())
                .sum::<f64>()
                / n;
            (d.experiments()
                .iter()
                .map(|e| e.y.column(j).iter().map(|v| (v - m).powi(2)).sum::<f64>())
                .sum::<f64>()
                / n)
                .sqrt()
        })
        .collect();
    Excitation {
        samples: d.n_samples(),
        std,
    }
}

fn segments(list: &[Interval], key: &str) -> Result<Vec<Segment>> {
    list.iter()
        .enumerate()
        .map(|(i, iv)| {
            Ok(Segment {
                experiment: Some(usize::from(iv.flight) - 2),
                interval: TimeInterval::new(iv.from, iv.to).ctx(|| format!("{key}[{i}]"))?,
            })
        })
        .collect()
}

fn one_model(
    cfg: &Config,
    ex: &Experiments,
    flights23: &IoData,
    kind: ModelKey,
    sets: &DataSets,
) -> Result<IdentifiedModel> {
    let id = &cfg.identification;
    let (key, label) = (kind.key(), kind.label());
    let virt = kind == ModelKey::Virtual;
    let est = select(
        &ex.flights,
        &sets.estimate,
        virt,
        &format!("identification.{key}.estimate"),
    )?;
    let val = select(
        &ex.flights,
        &sets.validate,
        virt,
        &format!("identification.{key}.validate"),
    )?;
    let mut spec = thesis_spec(if virt {
        ModelKind::Virtual
    } else {
        ModelKind::BlackBox
    });
    spec.estimate = segments(&sets.estimate, &format!("identification.{key}.estimate"))?;
    spec.validate = segments(&sets.validate, &format!("identification.{key}.validate"))?;
    spec.order = Some(id.order);
    spec.reduce = Some(id.reduced_order);
    spec.match_dc = id.match_dc;
    spec.max_iterations = id.pem_max_iterations;
    spec.horizons = id.horizons.clone();
    let idr = identify(flights23, &spec).ctx(|| format!("identifying the {label} model"))?;
    let offsets = idr.offsets.clone();
    let mapped = match &spec.input_map {
        Some(m) => flights23
            .map_inputs(&m.matrix, m.names.clone())
            .ctx(|| format!("the {label} model's inputs"))?,
        None => flights23.clone(),
    };
    let val0 = select_segments(&mapped, &spec.validate)
        .and_then(|d| d.subtract(&offsets))
        .ctx(|| format!("the {label} model's validation data"))?;
    let est0 = select_segments(&mapped, &spec.estimate)
        .and_then(|d| d.subtract(&offsets))
        .ctx(|| format!("the {label} model's estimation data"))?;
    let mut rep = idr.validation.clone();
    let mut rep_full = idr.full_validation.clone().unwrap_or_else(|| rep.clone());
    let model = idr.model.clone();
    if id.residual_lags != 25 {
        rep_full.residuals = resid(&idr.full_model, &val0, id.residual_lags)
            .ctx(|| format!("residuals of the {label} model"))?;
        rep.residuals = resid(&model, &val0, id.residual_lags)
            .ctx(|| format!("residuals of the {label} model"))?;
    }
    let zeros = transmission_zeros(&model).map_err(|e| e.to_string());
    let ss = model
        .to_ss_model(
            Some(&offsets.u0),
            Some(&offsets.y0),
            Some(&idr.input_names),
            Some(&idr.output_names),
        )
        .ctx(|| format!("the {label} model as kestrel.ss.v1"))?;
    let full_ss = idr
        .full_model
        .to_ss_model(
            Some(&offsets.u0),
            Some(&offsets.y0),
            Some(&idr.input_names),
            Some(&idr.output_names),
        )
        .ctx(|| format!("the {label} model as kestrel.ss.v1"))?;
    // Figures 7.8-7.11 on the longest validation experiment.
    let cmp =
        kestrel_sysid::compare(&model, &val0).ctx(|| format!("simulating the {label} model"))?;
    let (ei, e) = val0
        .experiments()
        .iter()
        .enumerate()
        .max_by_key(|(_, e)| e.len())
        .ok_or_else(|| PipelineError::Data(format!("the {label} model: no validation data")))?;
    let x0 = estimate_x0_predictor(&model, &e.u, &e.y)
        .ctx(|| format!("the {label} model's initial state"))?;
    let pred = model
        .predict_k_step(&e.u, &e.y, &x0, 5)
        .ctx(|| format!("the {label} model's 5-step prediction"))?;
    Ok(IdentifiedModel {
        kind,
        order: id.order,
        reduced_order: id.reduced_order,
        ss,
        full_ss,
        y0: offsets.y0.clone(),
        validation: rep,
        full_validation: rep_full,
        pem: [&idr.pem, &idr.pem_noise]
            .iter()
            .filter_map(|p| **p)
            .collect(),
        hankel_singular_values: idr
            .reduction
            .as_ref()
            .map(|r| r.hankel_singular_values.clone())
            .unwrap_or_default(),
        zeros,
        estimation: excitation(&est),
        validation_data: excitation(&val),
        estimation_samples: est0.n_samples(),
        validation_samples: val0.n_samples(),
        simulation: OutputComparison {
            t: e.t.clone(),
            measured: e.y.clone(),
            model: cmp.simulated[ei].clone(),
            fit: Some(cmp.fit.clone()),
        },
        five_step: OutputComparison {
            t: e.t.clone(),
            measured: e.y.clone(),
            model: pred,
            fit: None,
        },
    })
}

/// Stage 3.
///
/// # Errors
/// Bad intervals; kestrel-sysid's errors.
pub fn run(cfg: &Config, ex: &Experiments) -> Result<Identification> {
    let flights23 = IoData::merge(&[
        ex.flight(2, "flight no. 2")?.io_data(false)?,
        ex.flight(3, "flight no. 3")?.io_data(false)?,
    ])
    .ctx(|| "flights no. 2 and 3".into())?;
    let id = &cfg.identification;
    Ok(Identification {
        blackbox: one_model(cfg, ex, &flights23, ModelKey::BlackBox, &id.blackbox)?,
        virtual_: one_model(cfg, ex, &flights23, ModelKey::Virtual, &id.virtual_)?,
    })
}
