//! What [`identify`](crate::workflow::identify()) returns, and the text
//! `kestrel identify` prints.

use super::choice::SelectionReport;
use super::prefilter::PrefilterChoice;
use super::spec::Start;
#[cfg(doc)]
use super::spec::{AfterReduction, Method, PemFocus};
use crate::data::Offsets;
use crate::error::Result;
use crate::model::InnovationModel;
use crate::pem::StopReason;
use crate::reduce::Zero;
use crate::validate::ValidationReport;
use core::fmt;
use kestrel_core::formats::SsModel;

/// Summary of the N4SID step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct N4sidSummary {
    /// Order used.
    pub order: usize,
    /// Order suggested from the singular values.
    pub suggested_order: usize,
    /// Horizon (block rows; PBSID: past lags) used.
    pub horizon: usize,
    /// The subspace method.
    pub start: Start,
}

/// Summary of the PEM step (stopping information).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PemSummary {
    /// Iterations done.
    pub iterations: usize,
    /// Free parameters.
    pub free_parameters: usize,
    /// Cost at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub cost: f64,
    /// Why the search stopped.
    pub stop: StopReason,
}

/// Summary of the reduction step.
#[derive(Clone, Debug, PartialEq)]
pub struct ReductionSummary {
    /// Order before reduction.
    pub from: usize,
    /// Order after reduction.
    pub to: usize,
    /// Hankel singular values of the full model (stable part).
    pub hankel_singular_values: Vec<f64>,
    /// A-priori error bound.
    pub error_bound: f64,
}

/// Everything [`identify`](crate::workflow::identify()) produced.
#[derive(Clone, Debug)]
pub struct IdentifyReport {
    /// Estimation samples (all experiments).
    pub estimation_samples: usize,
    /// Estimation experiments.
    pub experiments: usize,
    /// Sample time.
    pub ts: f64,
    /// The removed operating point (in the units of the mapped inputs).
    pub offsets: Offsets,
    /// Input names of the model.
    pub input_names: Vec<String>,
    /// Output names of the model.
    pub output_names: Vec<String>,
    /// The N4SID step.
    pub n4sid: N4sidSummary,
    /// The PEM step (`None` for [`Method::N4sid`]).
    pub pem: Option<PemSummary>,
    /// The noise-model stage of [`PemFocus::SimulationThenNoise`] and
    /// [`PemFocus::MultiStepThenNoise`].
    pub pem_noise: Option<PemSummary>,
    /// The PEM refit of the reduced model ([`AfterReduction`]); with
    /// [`AfterReduction::All`] and [`PemFocus::SimulationThenNoise`], its
    /// noise-model stage.
    pub pem_reduced: Option<PemSummary>,
    /// The model of the identified order (before reduction).
    pub full_model: InnovationModel,
    /// The reduction step, when asked for.
    pub reduction: Option<ReductionSummary>,
    /// The final model (reduced when asked for).
    pub model: InnovationModel,
    /// Transmission zeros of the final model, or why they were not computed.
    pub zeros: core::result::Result<Vec<Zero>, String>,
    /// Whether the table is on separate validation data.
    pub on_validation_data: bool,
    /// Validation table of the final model.
    pub validation: ValidationReport,
    /// Validation table of the full model when it was reduced.
    pub full_validation: Option<ValidationReport>,
    /// What the automatic structure choice chose and why, or why it
    /// could not choose (the record too short for the folds: the spec is
    /// fitted as given); `None` when
    /// [`IdentifySpec::auto`](super::IdentifySpec::auto) is `None`.
    pub selection: Option<core::result::Result<SelectionReport, String>>,
    /// What the vibration pre-filter found ([`Prefilter::Auto`](super::Prefilter::Auto)).
    pub prefilter: Option<PrefilterChoice>,
}

impl IdentifyReport {
    /// The final model as `kestrel.ss.v1` with the removed offsets as `u0`/`y0`.
    pub fn to_ss_model(&self) -> Result<SsModel> {
        self.model.to_ss_model(
            Some(&self.offsets.u0),
            Some(&self.offsets.y0),
            Some(&self.input_names),
            Some(&self.output_names),
        )
    }
}

impl fmt::Display for IdentifyReport {
    /// The text `kestrel identify` prints.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(p) = &self.prefilter {
            let hz = |w: f64| w / (2.0 * core::f64::consts::PI);
            match p.cutoff {
                Some(c) => writeln!(
                    f,
                    "pre-filter: vibration peak at {:.1} Hz ({:.0} x the median power above it): low-pass at {:.1} Hz ({c:.1} rad/s), forward-backward",
                    hz(p.peak),
                    p.ratio,
                    hz(c)
                )?,
                None => writeln!(
                    f,
                    "pre-filter: none (largest peak at {:.1} Hz only {:.1} x the median power)",
                    hz(p.peak),
                    p.ratio
                )?,
            }
        }
        match &self.selection {
            Some(Ok(s)) => write!(f, "{s}")?,
            Some(Err(why)) => writeln!(f, "structure not chosen ({why}): fitted as given")?,
            None => {}
        }
        writeln!(
            f,
            "data: {} estimation samples in {} experiment(s), ts = {} s; {} order {} (suggested {}), {} {}",
            self.estimation_samples,
            self.experiments,
            self.ts,
            match self.n4sid.start {
                Start::N4sid => "N4SID",
                Start::Pbsid => "PBSID",
                Start::Arx => "ARX reduction",
                Start::Armax => "ARMAX reduction",
            },
            self.n4sid.order,
            self.n4sid.suggested_order,
            match self.n4sid.start {
                Start::N4sid => "horizon",
                Start::Pbsid => "past",
                Start::Arx | Start::Armax => "lags",
            },
            self.n4sid.horizon
        )?;
        if let Some(p) = &self.pem {
            writeln!(
                f,
                "PEM: {} iterations, {} free parameters, cost {:.6} -> {:.6}, stopped: {:?}",
                p.iterations, p.free_parameters, p.initial_cost, p.cost, p.stop
            )?;
        }
        if let Some(p) = &self.pem_noise {
            writeln!(
                f,
                "PEM noise model (K, dynamics fixed): {} iterations, {} free parameters, cost {:.6} -> {:.6}, stopped: {:?}",
                p.iterations, p.free_parameters, p.initial_cost, p.cost, p.stop
            )?;
        }
        if let Some(r) = &self.reduction {
            writeln!(
                f,
                "balred {} -> {}: Hankel singular values {:.4?}, error bound {:.4}",
                r.from, r.to, r.hankel_singular_values, r.error_bound
            )?;
        }
        if let Some(p) = &self.pem_reduced {
            writeln!(
                f,
                "PEM refit after balred: {} iterations, {} free parameters, one-step cost {:.6} -> {:.6}, stopped: {:?}",
                p.iterations, p.free_parameters, p.initial_cost, p.cost, p.stop
            )?;
        }
        match &self.zeros {
            Ok(z) => {
                let nmp: Vec<String> = z
                    .iter()
                    .filter(|z| z.non_minimum_phase)
                    .map(|z| format!("{:.4}{:+.4}i", z.z.re, z.z.im))
                    .collect();
                writeln!(
                    f,
                    "transmission zeros: {} ({} outside the unit circle{}{})",
                    z.len(),
                    nmp.len(),
                    if nmp.is_empty() { "" } else { ": " },
                    nmp.join(", ")
                )?;
            }
            Err(e) => writeln!(f, "transmission zeros: not computed ({e})")?,
        }
        f.write_str(if self.on_validation_data {
            "validation data:\n"
        } else {
            "no --validate intervals: table on the estimation data\n"
        })?;
        write!(f, "{}", self.validation)
    }
}
