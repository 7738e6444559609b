//! Validation: simulation fit (`compare`), k-step-ahead prediction fit,
//! residual analysis (`resid`), each with the persistence baseline.

use crate::arx::arx_baseline;
use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::lstsq;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};
use std::fmt;
use std::ops::RangeInclusive;

pub use crate::fit::fit_percent;

fn check_model_data(model: &InnovationModel, data: &IoData) -> Result<()> {
    if model.nu() != data.nu() {
        return Err(SysidError::dim(
            "model inputs vs data",
            data.nu(),
            model.nu(),
        ));
    }
    if model.ny() != data.ny() {
        return Err(SysidError::dim(
            "model outputs vs data",
            data.ny(),
            model.ny(),
        ));
    }
    Ok(())
}

/// Least-squares initial state of the simulation: `y - y_sim(x0 = 0) = C A^k x0`.
pub fn estimate_x0_simulation(
    model: &InnovationModel,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
) -> Result<DVector<f64>> {
    let zero = DVector::zeros(model.nx());
    let r = y - model.simulate(u, &zero)?;
    Ok(x0_from_free_response(&model.a, &model.c, &r))
}

/// Least-squares initial state of the one-step predictor:
/// `e(x0 = 0) = C (A - KC)^k x0 + e`.
pub fn estimate_x0_predictor(
    model: &InnovationModel,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
) -> Result<DVector<f64>> {
    let zero = DVector::zeros(model.nx());
    let r = model.predict_one_step(u, y, &zero)?.residuals;
    let abar = &model.a - &model.k * &model.c;
    Ok(x0_from_free_response(&abar, &model.c, &r))
}

fn x0_from_free_response(a: &DMatrix<f64>, c: &DMatrix<f64>, r: &DMatrix<f64>) -> DVector<f64> {
    let (n, ny, nt) = (a.nrows(), c.nrows(), r.nrows());
    // Only the first samples matter for a stable free response; cap the work.
    let mut nt = nt.min(2000);
    let mut phi = DMatrix::zeros(nt * ny, n);
    let mut rhs = DMatrix::zeros(nt * ny, 1);
    let mut ca = c.clone();
    for t in 0..nt {
        // An unstable model's free response overflows: the samples after
        // that carry no information about x0 (and would poison the SVD).
        if ca.iter().any(|v| !v.is_finite() || v.abs() > 1e150) {
            nt = t.max(1);
            break;
        }
        phi.rows_mut(t * ny, ny).copy_from(&ca);
        for o in 0..ny {
            rhs[(t * ny + o, 0)] = r[(t, o)];
        }
        ca = &ca * a;
    }
    let (phi, rhs) = (
        phi.rows(0, nt * ny).into_owned(),
        rhs.rows(0, nt * ny).into_owned(),
    );
    let x = lstsq(&phi, &rhs);
    DVector::from_column_slice(x.as_slice())
}

/// Result of [`compare`].
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Fit per output (4.11), percent.
    pub fit: Vec<f64>,
    /// Simulated outputs per experiment.
    pub simulated: Vec<DMatrix<f64>>,
    /// Estimated initial state per experiment.
    pub x0: Vec<DVector<f64>>,
}

/// Simulation fit of a model on data (MATLAB's `compare`): each
/// experiment is simulated from its least-squares initial state.
pub fn compare(model: &InnovationModel, data: &IoData) -> Result<Comparison> {
    check_model_data(model, data)?;
    let mut sims = Vec::new();
    let mut x0s = Vec::new();
    let mut ys = Vec::new();
    for e in data.experiments() {
        let x0 = estimate_x0_simulation(model, &e.u, &e.y)?;
        sims.push(model.simulate(&e.u, &x0)?);
        x0s.push(x0);
        ys.push(e.y.clone());
    }
    Ok(Comparison {
        fit: fit_percent(&ys, &sims),
        simulated: sims,
        x0: x0s,
    })
}

/// k-step-ahead prediction fit of a model (4.12), per output, percent.
/// Each experiment's predictor starts from its least-squares initial state.
pub fn predict_fit(model: &InnovationModel, data: &IoData, k: usize) -> Result<Vec<f64>> {
    check_model_data(model, data)?;
    let mut ys = Vec::new();
    let mut ps = Vec::new();
    for e in data.experiments() {
        let x0 = estimate_x0_predictor(model, &e.u, &e.y)?;
        ps.push(model.predict_k_step(&e.u, &e.y, &x0, k)?);
        ys.push(e.y.clone());
    }
    Ok(fit_percent(&ys, &ps))
}

/// Fit of the persistence predictor `yhat(t) = y(t - k)` (the first
/// sample for `t < k`); `k = None` holds the first sample throughout
/// (the persistence "simulation").
pub fn persistence_fit(data: &IoData, k: Option<usize>) -> Vec<f64> {
    let mut ys = Vec::new();
    let mut ps = Vec::new();
    for e in data.experiments() {
        let n = e.len();
        let p = DMatrix::from_fn(n, data.ny(), |t, j| match k {
            Some(k) => e.y[(t.saturating_sub(k), j)],
            None => e.y[(0, j)],
        });
        ys.push(e.y.clone());
        ps.push(p);
    }
    fit_percent(&ys, &ps)
}

/// Residual correlations of one output.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputResiduals {
    /// The output's name.
    pub name: String,
    /// Normalised autocorrelation for lags `0..=max_lag` (lag 0 is 1).
    pub autocorr: Vec<f64>,
    /// Normalised cross-correlation with each input for lags
    /// `-max_lag..=max_lag` (index `max_lag + tau`): residual at `t + tau`
    /// against input at `t`.
    pub crosscorr: Vec<Vec<f64>>,
    /// Lags `1..=max_lag` of the autocorrelation outside the band.
    pub auto_outside: usize,
    /// Lags `0..=max_lag` of the cross-correlations (all inputs) outside the band.
    pub cross_outside: usize,
    /// Negative lags of the cross-correlations outside the band (feedback,
    /// not counted against the model).
    pub cross_outside_negative: usize,
    /// Verdict: the residuals are white.
    pub white: bool,
    /// Verdict: the residuals are uncorrelated with past and present inputs.
    pub independent: bool,
}

/// Result of [`resid`].
#[derive(Clone, Debug, PartialEq)]
pub struct ResidualAnalysis {
    /// Largest lag.
    pub max_lag: usize,
    /// The 99 % confidence band `2.576 / sqrt(N)` of a normalised
    /// correlation under the hypothesis of white residuals independent of
    /// the inputs.
    pub bound: f64,
    /// Input names.
    pub inputs: Vec<String>,
    /// Per output.
    pub outputs: Vec<OutputResiduals>,
}

/// Residual analysis (4.13)-(4.14), MATLAB's `resid`: autocorrelation of
/// the one-step prediction errors and their cross-correlation with the
/// inputs, lags `-max_lag..=max_lag`, with 99 % bands.
///
/// Verdicts: with `L` lags tested, a test passes when at most
/// `1 + L / 100` of them lie outside the band (under the null hypothesis
/// about 1 % lie outside by chance). The cross-correlation verdict uses
/// lags `tau >= 0` only; correlation at negative lags means feedback from
/// the residual to later inputs (closed-loop data), not a model error.
pub fn resid(model: &InnovationModel, data: &IoData, max_lag: usize) -> Result<ResidualAnalysis> {
    check_model_data(model, data)?;
    let mut res = Vec::new();
    let mut us = Vec::new();
    for e in data.experiments() {
        let x0 = estimate_x0_predictor(model, &e.u, &e.y)?;
        res.push(model.predict_one_step(&e.u, &e.y, &x0)?.residuals);
        us.push(e.u.clone());
    }
    let n: usize = res.iter().map(|r| r.nrows()).sum();
    if n <= max_lag + 1 {
        return Err(SysidError::TooFewSamples {
            what: format!("residual analysis with {max_lag} lags"),
            needed: max_lag + 2,
            found: n,
        });
    }
    let nf = n as f64;
    let mean_of =
        |ms: &[DMatrix<f64>], j: usize| ms.iter().map(|m| m.column(j).sum()).sum::<f64>() / nf;
    // R_ab(tau) = 1/N sum_t a(t + tau) b(t), within experiments.
    let corr = |a: &[DMatrix<f64>],
                ja: usize,
                ma: f64,
                b: &[DMatrix<f64>],
                jb: usize,
                mb: f64,
                tau: isize| {
        let mut s = 0.0;
        for (x, z) in a.iter().zip(b) {
            let len = x.nrows() as isize;
            for t in 0..len {
                let ta = t + tau;
                if ta >= 0 && ta < len {
                    s += (x[(ta as usize, ja)] - ma) * (z[(t as usize, jb)] - mb);
                }
            }
        }
        s / nf
    };
    let bound = 2.576 / nf.sqrt();
    let m = max_lag as isize;
    let allowed = |count: usize| 1 + count / 100;
    let mut outputs = Vec::new();
    for j in 0..data.ny() {
        let me = mean_of(&res, j);
        let r0 = corr(&res, j, me, &res, j, me, 0);
        let autocorr: Vec<f64> = (0..=m)
            .map(|tau| {
                if r0 > 0.0 {
                    corr(&res, j, me, &res, j, me, tau) / r0
                } else {
                    0.0
                }
            })
            .collect();
        let mut crosscorr = Vec::new();
        let mut cross_outside = 0;
        let mut cross_neg = 0;
        for q in 0..data.nu() {
            let mu = mean_of(&us, q);
            let u0 = corr(&us, q, mu, &us, q, mu, 0);
            let norm = (r0 * u0).sqrt();
            let c: Vec<f64> = (-m..=m)
                .map(|tau| {
                    if norm > 0.0 {
                        corr(&res, j, me, &us, q, mu, tau) / norm
                    } else {
                        0.0
                    }
                })
                .collect();
            for (i, v) in c.iter().enumerate() {
                if v.abs() > bound {
                    if i >= max_lag {
                        cross_outside += 1;
                    } else {
                        cross_neg += 1;
                    }
                }
            }
            crosscorr.push(c);
        }
        let auto_outside = autocorr.iter().skip(1).filter(|v| v.abs() > bound).count();
        outputs.push(OutputResiduals {
            name: data.output_names()[j].clone(),
            white: auto_outside <= allowed(max_lag),
            independent: cross_outside <= allowed((max_lag + 1) * data.nu()),
            autocorr,
            crosscorr,
            auto_outside,
            cross_outside,
            cross_outside_negative: cross_neg,
        });
    }
    Ok(ResidualAnalysis {
        max_lag,
        bound,
        inputs: data.input_names().to_vec(),
        outputs,
    })
}

/// What a row of a fit table evaluates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Predictor {
    /// The model under validation.
    Model,
    /// Persistence ([`persistence_fit`]): `y(t + k) = y(t)`; in
    /// simulation the first sample held throughout.
    Persistence,
    /// The best least-squares ARX of the baseline
    /// ([`ValidationReport::add_arx_baseline`]).
    BestArx {
        /// Its lag count (`na = nb`), the best for this horizon.
        lags: usize,
    },
}

/// How far ahead a row of a fit table predicts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Horizon {
    /// Simulation: from the inputs alone (the initial state estimated).
    Simulation,
    /// `k`-step-ahead prediction from the outputs up to `t - k`.
    Steps(usize),
}

/// One row of a fit table: a predictor, its horizon and its fit per
/// output.
#[derive(Clone, Debug, PartialEq)]
pub struct FitRow {
    /// What was evaluated.
    pub predictor: Predictor,
    /// How far ahead.
    pub horizon: Horizon,
    /// The row's label in the table, e.g. `"model simulation"`,
    /// `"model 5-step"`, `"persistence 5-step"`,
    /// `"best ARX 5-step (4 lags)"` ([`FitRow::new`] writes it).
    pub label: String,
    /// Fit per output, percent.
    pub fit: Vec<f64>,
}

impl FitRow {
    /// A row with its label written from `predictor` and `horizon`.
    pub fn new(predictor: Predictor, horizon: Horizon, fit: Vec<f64>) -> Self {
        let ahead = match horizon {
            Horizon::Simulation => "simulation".to_string(),
            Horizon::Steps(k) => format!("{k}-step"),
        };
        let label = match predictor {
            Predictor::Model => format!("model {ahead}"),
            Predictor::Persistence => format!("persistence {ahead}"),
            Predictor::BestArx { lags } => format!("best ARX {ahead} ({lags} lags)"),
        };
        FitRow {
            predictor,
            horizon,
            label,
            fit,
        }
    }

    /// The mean fit over outputs.
    pub fn mean(&self) -> f64 {
        self.fit.iter().sum::<f64>() / self.fit.len().max(1) as f64
    }
}

/// A validation report: simulation fit, k-step fits and the persistence
/// baseline for each, and the residual analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct ValidationReport {
    /// Output names (table columns).
    pub outputs: Vec<String>,
    /// Rows: model simulation, then model and persistence for each horizon.
    pub rows: Vec<FitRow>,
    /// Residual analysis of the one-step prediction errors.
    pub residuals: ResidualAnalysis,
}

impl ValidationReport {
    /// The row with the given label.
    pub fn row(&self, label: &str) -> Option<&FitRow> {
        self.rows.iter().find(|r| r.label == label)
    }

    /// The first row of `predictor` at `horizon`.
    pub fn row_of(&self, predictor: Predictor, horizon: Horizon) -> Option<&FitRow> {
        self.rows
            .iter()
            .find(|r| r.predictor == predictor && r.horizon == horizon)
    }
}

/// Validates a model on data: simulation fit, k-step fits for every
/// horizon in `horizons`, the persistence baseline beside each, and the
/// residual analysis with lags `-25..=25`.
pub fn validate(
    model: &InnovationModel,
    data: &IoData,
    horizons: &[usize],
) -> Result<ValidationReport> {
    let mut rows = vec![
        FitRow::new(
            Predictor::Model,
            Horizon::Simulation,
            compare(model, data)?.fit,
        ),
        FitRow::new(
            Predictor::Persistence,
            Horizon::Simulation,
            persistence_fit(data, None),
        ),
    ];
    for &k in horizons {
        let h = Horizon::Steps(k);
        rows.push(FitRow::new(
            Predictor::Model,
            h,
            predict_fit(model, data, k)?,
        ));
        rows.push(FitRow::new(
            Predictor::Persistence,
            h,
            persistence_fit(data, Some(k)),
        ));
    }
    Ok(ValidationReport {
        outputs: data.output_names().to_vec(),
        rows,
        residuals: resid(model, data, 25)?,
    })
}

impl ValidationReport {
    /// Adds the best-ARX baseline rows (least squares on `est`, the best
    /// lag count in `lags` on `val` for each horizon, an optimistic
    /// baseline: [`arx_baseline`]) after the persistence row of each
    /// horizon, labelled `best ARX k-step (n lags)`. Returns whether they
    /// were added: a record too short for every lag count adds none.
    pub fn add_arx_baseline(
        &mut self,
        est: &IoData,
        val: &IoData,
        lags: RangeInclusive<usize>,
        horizons: &[usize],
    ) -> Result<bool> {
        let b = match arx_baseline(est, val, lags, horizons) {
            Ok(b) => b,
            Err(SysidError::TooFewSamples { .. }) => return Ok(false),
            Err(e) => return Err(e),
        };
        for row in &b.rows {
            let h = Horizon::Steps(row.horizon);
            let fit_row = FitRow::new(Predictor::BestArx { lags: row.lags }, h, row.fit.clone());
            let after = |r: &FitRow| r.predictor == Predictor::Persistence && r.horizon == h;
            match self.rows.iter().position(after) {
                Some(i) => self.rows.insert(i + 1, fit_row),
                None => self.rows.push(fit_row),
            }
        }
        Ok(true)
    }

    /// The best-ARX baseline row of horizon `k`, if added.
    pub fn arx_row(&self, k: usize) -> Option<&FitRow> {
        self.rows.iter().find(|r| {
            matches!(r.predictor, Predictor::BestArx { .. }) && r.horizon == Horizon::Steps(k)
        })
    }

    /// The model against its baselines at each prediction horizon of the
    /// table (mean fits over the outputs), in the table's order.
    pub fn baseline_comparisons(&self) -> Vec<BaselineComparison> {
        self.rows
            .iter()
            .filter_map(|r| {
                let Horizon::Steps(k) = r.horizon else {
                    return None;
                };
                if r.predictor != Predictor::Model {
                    return None;
                }
                let persistence = self
                    .row_of(Predictor::Persistence, Horizon::Steps(k))?
                    .mean();
                Some(BaselineComparison {
                    horizon: k,
                    model: r.mean(),
                    persistence,
                    best_arx: self.arx_row(k).map(FitRow::mean),
                })
            })
            .collect()
    }
}

/// The model's mean k-step fit beside the persistence and best-ARX
/// baselines of the same horizon ([`ValidationReport::baseline_comparisons`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaselineComparison {
    /// Prediction steps `k`.
    pub horizon: usize,
    /// The model's mean k-step fit, percent.
    pub model: f64,
    /// Persistence's mean k-step fit (`y(t + k) = y(t)`), percent.
    pub persistence: f64,
    /// The best ARX's mean k-step fit, percent, when the baseline was added.
    pub best_arx: Option<f64>,
}

impl BaselineComparison {
    /// Whether the model's fit is above every baseline present.
    pub fn beats_baselines(&self) -> bool {
        self.model > self.persistence && self.best_arx.is_none_or(|a| self.model > a)
    }
}

impl fmt::Display for BaselineComparison {
    /// `5-step: ahead of persistence by 36.40, behind the best ARX by 0.77`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let side = |d: f64| if d > 0.0 { "ahead of" } else { "behind" };
        let d = self.model - self.persistence;
        write!(
            f,
            "{}-step: {} persistence by {:.2}",
            self.horizon,
            side(d),
            d.abs()
        )?;
        if let Some(a) = self.best_arx {
            let d = self.model - a;
            write!(f, ", {} the best ARX by {:.2}", side(d), d.abs())?;
        }
        Ok(())
    }
}

impl fmt::Display for ValidationReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:<26}", "fit [%]")?;
        for o in &self.outputs {
            write!(f, "{o:>10}")?;
        }
        writeln!(f, "{:>10}", "mean")?;
        for r in &self.rows {
            write!(f, "{:<26}", r.label)?;
            for v in &r.fit {
                write!(f, "{v:>10.2}")?;
            }
            writeln!(f, "{:>10.2}", r.mean())?;
        }
        let against = self.baseline_comparisons();
        if !against.is_empty() {
            let parts: Vec<String> = against.iter().map(|c| c.to_string()).collect();
            let verdict = if against.iter().all(BaselineComparison::beats_baselines) {
                "the model beats every baseline"
            } else {
                "the model does not beat every baseline"
            };
            writeln!(
                f,
                "mean fit against the baselines: {}; {verdict}",
                parts.join("; ")
            )?;
        }
        let ra = &self.residuals;
        writeln!(
            f,
            "residuals (lags -{0}..{0}, 99% band +-{1:.4}):",
            ra.max_lag, ra.bound
        )?;
        for o in &ra.outputs {
            writeln!(
                f,
                "  {:<10} autocorr outside {:>2}/{} -> {:<9} cross(tau>=0) outside {:>2}/{} -> {:<11} (tau<0: {})",
                o.name,
                o.auto_outside,
                ra.max_lag,
                if o.white { "white" } else { "NOT white" },
                o.cross_outside,
                (ra.max_lag + 1) * ra.inputs.len(),
                if o.independent {
                    "independent"
                } else {
                    "CORRELATED"
                },
                o.cross_outside_negative
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic;

    #[test]
    fn baseline_comparisons_pair_each_horizon_with_its_baselines() {
        use Horizon::{Simulation, Steps};
        use Predictor::{BestArx, Model, Persistence};
        let row = |p: Predictor, h: Horizon, fit: [f64; 2]| FitRow::new(p, h, fit.to_vec());
        let report = ValidationReport {
            outputs: vec!["p".into(), "q".into()],
            rows: vec![
                row(Model, Simulation, [10.0, 20.0]),
                row(Persistence, Simulation, [0.0, 0.0]),
                row(Model, Steps(1), [90.0, 92.0]),
                row(Persistence, Steps(1), [80.0, 80.0]),
                row(BestArx { lags: 4 }, Steps(1), [92.0, 92.0]),
                row(Model, Steps(5), [50.0, 60.0]),
                row(Persistence, Steps(5), [10.0, 20.0]),
            ],
            residuals: ResidualAnalysis {
                max_lag: 1,
                bound: 0.1,
                inputs: Vec::new(),
                outputs: Vec::new(),
            },
        };
        let labels: Vec<&str> = report.rows.iter().map(|r| r.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "model simulation",
                "persistence simulation",
                "model 1-step",
                "persistence 1-step",
                "best ARX 1-step (4 lags)",
                "model 5-step",
                "persistence 5-step"
            ]
        );
        assert_eq!(report.arx_row(1), Some(&report.rows[4]));
        assert_eq!(report.arx_row(5), None);
        let c = report.baseline_comparisons();
        assert_eq!(
            c,
            vec![
                BaselineComparison {
                    horizon: 1,
                    model: 91.0,
                    persistence: 80.0,
                    best_arx: Some(92.0),
                },
                BaselineComparison {
                    horizon: 5,
                    model: 55.0,
                    persistence: 15.0,
                    best_arx: None,
                },
            ]
        );
        assert!(!c[0].beats_baselines());
        assert!(c[1].beats_baselines());
        assert_eq!(
            c[0].to_string(),
            "1-step: ahead of persistence by 11.00, behind the best ARX by 1.00"
        );
        let text = report.to_string();
        assert!(text.contains(
            "mean fit against the baselines: 1-step: ahead of persistence by 11.00, behind the best ARX by 1.00; \
             5-step: ahead of persistence by 40.00; the model does not beat every baseline"
        ));
    }

    #[test]
    fn fit_is_100_for_perfect_and_0_for_mean() {
        let y = DMatrix::from_fn(50, 2, |t, j| (t * (j + 2)) as f64 % 7.0);
        assert!(
            fit_percent(std::slice::from_ref(&y), std::slice::from_ref(&y))
                .iter()
                .all(|f| (f - 100.0).abs() < 1e-12)
        );
        let mean = DMatrix::from_fn(50, 2, |_, j| y.column(j).mean());
        assert!(
            fit_percent(std::slice::from_ref(&y), &[mean])
                .iter()
                .all(|f| f.abs() < 1e-12)
        );
    }

    #[test]
    fn true_model_gives_white_residuals_and_exact_simulation() {
        let m = synthetic::random_model(3, 2, 2, 5, 0.9);
        // Noise-free: simulation fit 100 with the estimated initial state.
        let mut clean = m.clone();
        clean.k.fill(0.0);
        let d = synthetic::simulate(&clean, 800, 0.0, 3).unwrap();
        let c = compare(&clean, &d).unwrap();
        assert!(c.fit.iter().all(|f| *f > 99.999), "{:?}", c.fit);
        // Noisy with the true noise model: residuals white and independent.
        let d = synthetic::simulate(&m, 4000, 0.3, 4).unwrap();
        let r = resid(&m, &d, 25).unwrap();
        for o in &r.outputs {
            assert!(o.white && o.independent, "{o:?}");
            assert!((o.autocorr[0] - 1.0).abs() < 1e-12);
        }
        // A wrong model (no noise model, perturbed dynamics) fails whiteness.
        let mut wrong = m.clone();
        wrong.k.fill(0.0);
        wrong.a *= 0.5;
        let r = resid(&wrong, &d, 25).unwrap();
        assert!(r.outputs.iter().any(|o| !o.white || !o.independent));
    }

    #[test]
    fn persistence_one_step_fit_closed_form() {
        // y = t: y(t) - y(t-1) = 1 except t = 0.
        let n = 20;
        let y = DMatrix::from_fn(n, 1, |t, _| t as f64);
        let d = IoData::new(
            1.0,
            DMatrix::from_fn(n, 1, |t, _| (t % 3) as f64),
            y.clone(),
        )
        .unwrap();
        let f = persistence_fit(&d, Some(1))[0];
        let mean = (n - 1) as f64 / 2.0;
        let den: f64 = (0..n).map(|t| (t as f64 - mean).powi(2)).sum();
        let want = 100.0 * (1.0 - ((n - 1) as f64 / den).sqrt());
        assert!((f - want).abs() < 1e-12);
    }

    #[test]
    fn unstable_model_is_compared_without_hanging() {
        // A predictor that diverges (A = 1.5 I): the free response overflows
        // long before 2000 samples. compare used to hang in the SVD of the
        // overflowed regressor; now it returns (a finite, very poor fit or an
        // error, never a loop).
        let m = synthetic::random_model(3, 2, 2, 5, 0.9);
        let d = synthetic::simulate(&m, 3000, 0.3, 4).unwrap();
        let mut bad = m.clone();
        bad.a = DMatrix::identity(3, 3) * 1.5;
        if let Ok(c) = compare(&bad, &d) {
            assert!(
                c.fit.iter().all(|f| !f.is_finite() || *f < 50.0),
                "{:?}",
                c.fit
            );
        }
    }

    #[test]
    fn mismatched_model_is_an_error() {
        let m = synthetic::random_model(2, 1, 1, 1, 0.5);
        let d = IoData::new(1.0, DMatrix::zeros(10, 2), DMatrix::zeros(10, 1)).unwrap();
        assert!(compare(&m, &d).is_err());
    }
}
