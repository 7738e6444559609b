//! A feedback (closed-loop) test: does the past of the outputs help
//! predict the inputs beyond what the inputs' own past predicts?
//!
//! On open-loop data the inputs are made without looking at the outputs,
//! so once the inputs' own past is known the outputs' past adds nothing;
//! in closed loop a controller computes the inputs from the outputs, and
//! the outputs' past predicts them (Granger causality from the outputs to
//! the inputs). [`feedback_test`] regresses each input `u_j(t)` on the
//! past of all inputs `u(t-1), ..., u(t-L)` (the restricted model), then
//! on those plus the outputs' past `y(t-1), ..., y(t-L)` (the full
//! model), and compares the residual sums of squares by the F statistic
//!
//! `F = ((RSS_0 - RSS_1) / (ny L)) / (RSS_1 / (M - (nu + ny) L))`
//!
//! with `ny L` and `M - (nu + ny) L` degrees of freedom (`M` regression
//! rows, summed over the experiments; regressors never reach across
//! experiments). Its p-value is the F distribution's upper tail.
//!
//! *The lag count.* Too few lags fake feedback on open-loop data: a
//! coloured input's own autoregression of a few lags leaves part of its
//! far past unexplained, and the outputs (a filtered copy of that past)
//! carry it (DaISy steam generator, estimation half: `F = 55` for `u1`
//! with 2 lags, about 1 with 10 or more). So `L` is the larger of the
//! lag count that minimises Akaike's criterion of the inputs' own
//! autoregression, `ln det S_l + 2 l nu^2 / M` over `1..=max_lags`, and
//! [`FeedbackSettings::min_lags`] (20), lowered only when the record is
//! too short for at least [`FeedbackSettings::rows_per_regressor`] rows
//! per regressor (or `L` as given, [`FeedbackSettings::lags`]).
//!
//! *The verdict.* Input `j` shows feedback when its p-value is below
//! `level / nu` (Bonferroni), and the data show feedback when any input
//! does: on open-loop data the chance that the test says feedback is at
//! most [`FeedbackSettings::level`] (0.01), whatever the number of inputs.
//!
//! *Lag 0 (the same sample).* A controller that computes `u(t)` from
//! `y(t)` reacts within the sample, and a plant with a feed-through `D`
//! makes `y(t)` depend on `u(t)`: both give the same correlation between
//! `u(t)` and `y(t)` given the past, which this regression cannot tell
//! apart. So the verdict uses the outputs' lags `1..=L` only; the
//! same-sample F test (adding `y(t)` to the full model) is reported
//! beside it ([`InputFeedback::same_sample`]) as information. A
//! controller that reacts within the sample also reacts to the outputs'
//! past through the plant's memory, which the lagged test sees (the
//! flight logs: `F` 2-9 at 10 lags).
//!
//! ```
//! use kestrel_sysid::{IoData, feedback_test, FeedbackSettings};
//! use nalgebra::DMatrix;
//! // Open loop: a coloured input drives a first-order plant.
//! let mut rng = kestrel_sysid::synthetic::Rng::new(1);
//! let n = 3000;
//! let (mut u, mut y) = (DMatrix::zeros(n, 1), DMatrix::zeros(n, 1));
//! for t in 1..n {
//!     u[(t, 0)] = 0.8 * u[(t - 1, 0)] + rng.normal();
//!     y[(t, 0)] = 0.9 * y[(t - 1, 0)] + u[(t - 1, 0)] + 0.5 * rng.normal();
//! }
//! let open = IoData::new(1.0, u.clone(), y.clone()).unwrap();
//! let r = feedback_test(&open, &FeedbackSettings::default()).unwrap();
//! assert!(!r.feedback, "{r}");
//! // Closed loop: the same plant with u(t) = -0.5 y(t - 1) + r(t).
//! for t in 1..n {
//!     u[(t, 0)] = -0.5 * y[(t - 1, 0)] + rng.normal();
//!     y[(t, 0)] = 0.9 * y[(t - 1, 0)] + u[(t - 1, 0)] + 0.5 * rng.normal();
//! }
//! let closed = IoData::new(1.0, u, y).unwrap();
//! let r = feedback_test(&closed, &FeedbackSettings::default()).unwrap();
//! assert!(r.feedback && r.inputs[0].lagged.p_value < 1e-6, "{r}");
//! println!("{r}");
//! ```

use crate::arx::CHUNK;
use crate::data::IoData;
use crate::error::{Result, SysidError};
use core::fmt;
use nalgebra::DMatrix;

/// Settings of [`feedback_test`].
#[derive(Clone, Debug, PartialEq)]
pub struct FeedbackSettings {
    /// The lag count `L`; `None`: chosen by the rule of the module docs
    /// (Akaike's criterion of the inputs' own autoregression, at least
    /// [`FeedbackSettings::min_lags`]).
    pub lags: Option<usize>,
    /// Fewest lags of the chosen count (20).
    pub min_lags: usize,
    /// Largest lag count Akaike's criterion tries (40).
    pub max_lags: usize,
    /// The false-alarm probability of the overall verdict on open-loop
    /// data (0.01); each input is tested at `level / nu`.
    pub level: f64,
    /// Fewest regression rows per regressor of the full model (5): a
    /// shorter record lowers the lag count.
    pub rows_per_regressor: usize,
}

impl Default for FeedbackSettings {
    fn default() -> Self {
        FeedbackSettings {
            lags: None,
            min_lags: 20,
            max_lags: 40,
            level: 0.01,
            rows_per_regressor: 5,
        }
    }
}

/// An F test: statistic, degrees of freedom and p-value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FTest {
    /// The F statistic.
    pub f: f64,
    /// Numerator degrees of freedom (the regressors added).
    pub df1: usize,
    /// Denominator degrees of freedom (rows minus the full model's regressors).
    pub df2: usize,
    /// `P(F(df1, df2) >= f)`.
    pub p_value: f64,
}

impl FTest {
    /// The test of `rss1` (full model, `k1` regressors) against `rss0`
    /// (restricted, `k1 - df1` regressors) on `rows` rows.
    fn new(rss0: f64, rss1: f64, df1: usize, k1: usize, rows: usize) -> Self {
        let df1 = df1.max(1);
        let df2 = rows.saturating_sub(k1).max(1);
        let f = ((rss0 - rss1).max(0.0) / df1 as f64) / (rss1.max(f64::MIN_POSITIVE) / df2 as f64);
        FTest {
            f,
            df1,
            df2,
            p_value: f_upper_tail(f, df1 as f64, df2 as f64),
        }
    }
}

/// The feedback test of one input.
#[derive(Clone, Debug, PartialEq)]
pub struct InputFeedback {
    /// The input's name.
    pub input: String,
    /// The outputs' lags `1..=L` added to the inputs' own past.
    pub lagged: FTest,
    /// The outputs' same sample `y(t)` added to the full model
    /// (information only: a feed-through looks the same).
    pub same_sample: FTest,
    /// Share of the restricted model's residual variance that the
    /// outputs' past explains, `1 - RSS_1 / RSS_0`.
    pub explained: f64,
    /// Whether `lagged.p_value < level / nu`.
    pub feedback: bool,
}

/// What [`feedback_test`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct FeedbackTest {
    /// The lag count `L` used.
    pub lags: usize,
    /// The lag count that minimises Akaike's criterion of the inputs'
    /// own autoregression (`None` with [`FeedbackSettings::lags`] given).
    pub aic_lags: Option<usize>,
    /// [`FeedbackSettings::min_lags`] of the test.
    pub min_lags: usize,
    /// Regression rows `M`.
    pub rows: usize,
    /// The overall level.
    pub level: f64,
    /// Per input, in the data's order.
    pub inputs: Vec<InputFeedback>,
    /// Whether any input shows feedback at `level / nu`.
    pub feedback: bool,
}

impl fmt::Display for FeedbackTest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let nu = self.inputs.len().max(1);
        writeln!(
            f,
            "feedback test (do the outputs' past {} lags predict the inputs beyond their own past? F test per input at {:.2e} = {} / {nu} inputs; lags: {}; {} rows): {}",
            self.lags,
            self.level / nu as f64,
            self.level,
            match self.aic_lags {
                Some(a) => format!(
                    "Akaike's choice for the inputs' own past {a}, at least {} unless the record is short",
                    self.min_lags
                ),
                None => "given".to_string(),
            },
            self.rows,
            if self.feedback {
                "FEEDBACK (closed loop)"
            } else {
                "no feedback found (open loop)"
            }
        )?;
        for i in &self.inputs {
            writeln!(
                f,
                "  {:<12} F = {:>8.2} ({}, {}), p = {:.2e}{}; same sample: F = {:.2}, p = {:.2e}",
                i.input,
                i.lagged.f,
                i.lagged.df1,
                i.lagged.df2,
                i.lagged.p_value,
                if i.feedback { ", feedback" } else { "" },
                i.same_sample.f,
                i.same_sample.p_value
            )?;
        }
        Ok(())
    }
}

/// Whether the past of `data`'s outputs helps predict its inputs beyond
/// the inputs' own past: the F test of the module docs, per input, and
/// the overall verdict at [`FeedbackSettings::level`].
///
/// Each experiment's own means are removed and every signal scaled to
/// unit variance first. Errors: [`SysidError::TooFewSamples`] when not
/// even one lag leaves [`FeedbackSettings::rows_per_regressor`] rows per
/// regressor, [`SysidError::ConstantInput`] /
/// [`SysidError::ConstantOutput`] for a signal that does not vary,
/// [`SysidError::InvalidArgument`] for a level outside `(0, 1)` or a
/// zero lag count.
pub fn feedback_test(data: &IoData, settings: &FeedbackSettings) -> Result<FeedbackTest> {
    if !(settings.level > 0.0 && settings.level < 1.0) {
        return Err(SysidError::invalid(format!(
            "the feedback test's level must be in (0, 1), found {}",
            settings.level
        )));
    }
    if settings.lags == Some(0) || settings.max_lags == 0 {
        return Err(SysidError::invalid(
            "the feedback test needs at least one lag",
        ));
    }
    let (nu, ny) = (data.nu(), data.ny());
    let signals = standardised(data)?;
    let rows_for = |l: usize| -> usize {
        signals
            .iter()
            .map(|s| s.nrows().saturating_sub(l))
            .sum::<usize>()
    };
    let regressors = |l: usize| (nu + ny) * l + ny;
    let per = settings.rows_per_regressor.max(1);
    let fits = |l: usize| rows_for(l) >= per * regressors(l).max(1);
    if !fits(1) {
        return Err(SysidError::TooFewSamples {
            what: format!("the feedback test ({per} rows per regressor at one lag)"),
            needed: per * regressors(1) + 1,
            found: data.n_samples(),
        });
    }
    let largest = (1..=settings.max_lags.max(settings.min_lags))
        .take_while(|&l| fits(l))
        .last()
        .unwrap_or(1);
    let (lags, aic_lags) = match settings.lags {
        Some(l) => (l.min(largest), None),
        None => {
            let a = aic_lags(&signals, nu, settings.max_lags.min(largest));
            (a.max(settings.min_lags).min(largest), Some(a))
        }
    };
    // Columns: u(t-1..t-L), y(t-1..t-L), y(t), then the targets u(t).
    let r = r_factor_of(&signals, nu, ny, lags, lags, true);
    let rows = rows_for(lags);
    let (k0, k1) = (nu * lags, (nu + ny) * lags);
    let targets = k1 + ny;
    let level = settings.level / nu as f64;
    let inputs: Vec<InputFeedback> = (0..nu)
        .map(|j| {
            let c = targets + j;
            let rss = |k: usize| (k..=c).map(|i| r[(i, c)] * r[(i, c)]).sum::<f64>();
            let (rss0, rss1, rss_same) = (rss(k0), rss(k1), rss(k1 + ny));
            let lagged = FTest::new(rss0, rss1, ny * lags, k1, rows);
            InputFeedback {
                input: data.input_names()[j].clone(),
                lagged,
                same_sample: FTest::new(rss1, rss_same, ny, k1 + ny, rows),
                explained: if rss0 > 0.0 { 1.0 - rss1 / rss0 } else { 0.0 },
                feedback: lagged.p_value < level,
            }
        })
        .collect();
    Ok(FeedbackTest {
        lags,
        aic_lags,
        min_lags: settings.min_lags,
        rows,
        level: settings.level,
        feedback: inputs.iter().any(|i| i.feedback),
        inputs,
    })
}

/// Per experiment, the `[u y]` samples with the experiment's own means
/// removed and every column scaled to unit variance over all experiments.
fn standardised(data: &IoData) -> Result<Vec<DMatrix<f64>>> {
    let (nu, ny) = (data.nu(), data.ny());
    let mut raw = vec![0.0f64; nu + ny];
    let mut out: Vec<DMatrix<f64>> = data
        .experiments()
        .iter()
        .map(|e| {
            let mut s = DMatrix::zeros(e.len(), nu + ny);
            s.columns_mut(0, nu).copy_from(&e.u);
            s.columns_mut(nu, ny).copy_from(&e.y);
            for (j, mut c) in s.column_iter_mut().enumerate() {
                raw[j] = raw[j].max(c.amax());
                let m = c.mean();
                c.add_scalar_mut(-m);
            }
            s
        })
        .collect();
    let n: usize = out.iter().map(|s| s.nrows()).sum();
    for j in 0..nu + ny {
        let ss: f64 = out.iter().map(|s| s.column(j).norm_squared()).sum();
        let std = (ss / n.max(1) as f64).sqrt();
        // Constant: no variation beyond rounding of the values' size.
        let varies = std.is_finite() && std > 1e-12 * raw[j];
        if !varies || std == 0.0 {
            return Err(if j < nu {
                SysidError::ConstantInput {
                    name: data.input_names()[j].clone(),
                    std,
                }
            } else {
                SysidError::ConstantOutput {
                    name: data.output_names()[j - nu].clone(),
                }
            });
        }
        for s in out.iter_mut() {
            s.column_mut(j).scale_mut(1.0 / std);
        }
    }
    Ok(out)
}

/// The upper-triangular `R` of the regression matrix `[u(t-1..t-lu),
/// y(t-1..t-ly), (y(t)), u(t)]` (rows `t >= max(lu, ly)` of every
/// experiment; lag-major columns) from the Cholesky factor of its Gram
/// matrix: the residual sum of squares of target column `c` on the
/// first `k` columns is `sum_{i = k..=c} R[i, c]^2`. The Gram matrix is
/// accumulated [`CHUNK`] rows at a time, as ARX's normal equations, so
/// the memory does not grow with the data's length.
fn r_factor_of(
    signals: &[DMatrix<f64>],
    nu: usize,
    ny: usize,
    lu: usize,
    ly: usize,
    same_sample: bool,
) -> DMatrix<f64> {
    let l = lu.max(ly);
    let cols = nu * lu + ny * ly + if same_sample { ny } else { 0 } + nu;
    let mut gram = DMatrix::zeros(cols, cols);
    for s in signals {
        let mut t0 = l;
        while t0 < s.nrows() {
            let m = CHUNK.min(s.nrows() - t0);
            let mut z = DMatrix::zeros(m, cols);
            for (r, t) in (t0..t0 + m).enumerate() {
                let mut c = 0;
                for k in 1..=lu {
                    for j in 0..nu {
                        z[(r, c)] = s[(t - k, j)];
                        c += 1;
                    }
                }
                for k in 1..=ly {
                    for j in 0..ny {
                        z[(r, c)] = s[(t - k, nu + j)];
                        c += 1;
                    }
                }
                if same_sample {
                    for j in 0..ny {
                        z[(r, c)] = s[(t, nu + j)];
                        c += 1;
                    }
                }
                for j in 0..nu {
                    z[(r, c)] = s[(t, j)];
                    c += 1;
                }
            }
            gram += z.tr_mul(&z);
            t0 += m;
        }
    }
    cholesky_upper(gram)
}

/// The upper Cholesky factor `R` (`G = R' R`) of a Gram matrix; a pivot
/// that vanishes (a regressor that is a combination of the earlier ones)
/// gives a zero row, so that regressor adds nothing.
fn cholesky_upper(mut g: DMatrix<f64>) -> DMatrix<f64> {
    let n = g.nrows();
    let scale = (0..n)
        .map(|i| g[(i, i)])
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let mut r = DMatrix::zeros(n, n);
    for i in 0..n {
        let d = g[(i, i)];
        if d <= 1e-13 * scale {
            continue;
        }
        let p = d.sqrt();
        for j in i..n {
            r[(i, j)] = g[(i, j)] / p;
        }
        for j in i + 1..n {
            for k in j..n {
                g[(j, k)] -= r[(i, j)] * r[(i, k)];
            }
        }
    }
    r
}

/// The lag count in `1..=max` that minimises Akaike's criterion
/// `ln det S_l + 2 l nu^2 / M` of the inputs' own autoregression (`S_l`
/// the residual covariance, all lag counts on the same rows `t >= max`).
fn aic_lags(signals: &[DMatrix<f64>], nu: usize, max: usize) -> usize {
    let max = max.max(1);
    let r = r_factor_of(signals, nu, 0, max, 0, false);
    let rows: usize = signals.iter().map(|s| s.nrows().saturating_sub(max)).sum();
    let m = rows.max(1) as f64;
    let t0 = nu * max;
    let mut best = (f64::INFINITY, 1);
    for l in 1..=max {
        let k = nu * l;
        // Residual Gram of the targets after the first k columns.
        let e = r.view((k, t0), (t0 + nu - k, nu));
        let s = e.transpose() * e / m;
        let det = s.determinant();
        if det.is_nan() || det <= 0.0 {
            continue;
        }
        let aic = det.ln() + 2.0 * (l * nu * nu) as f64 / m;
        if aic < best.0 {
            best = (aic, l);
        }
    }
    best.1
}

/// `P(F(d1, d2) >= f)`, the upper tail of the F distribution
/// ([`statrs`]'s Fisher-Snedecor survival function); `NaN` for degrees
/// of freedom that are not positive.
pub(crate) fn f_upper_tail(f: f64, d1: f64, d2: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    if !f.is_finite() {
        return if f > 0.0 { 0.0 } else { 1.0 };
    }
    if f <= 0.0 {
        return 1.0;
    }
    FisherSnedecor::new(d1, d2).map_or(f64::NAN, |d| d.sf(f))
}

#[cfg(test)]
mod tests {
    use super::{FeedbackSettings, f_upper_tail, feedback_test};
    use crate::data::{CsvColumns, IoData};
    use crate::error::SysidError;
    use crate::synthetic::Rng;
    use nalgebra::DMatrix;

    /// The F distribution's upper tail against scipy.stats.f.sf.
    #[test]
    fn f_upper_tail_matches_scipy() {
        for (f, d1, d2, want) in [
            (2.0, 5.0, 100.0, 0.085_079_850_274_591_54),
            (1.0, 40.0, 14000.0, 0.470_383_966_405_230_8),
            (0.5, 3.0, 10.0, 0.690_622_245_533_557_7),
            (55.3, 8.0, 14000.0, 4.391_475_422_263_309_5e-89),
            (3.0, 1.0, 1.0, 0.333_333_333_333_333_4),
            (1.2, 80.0, 13800.0, 0.108_084_433_562_476_39),
            (10.0, 2.0, 7.0, 0.008_872_989_457_173_155),
        ] {
            let p = f_upper_tail(f, d1, d2);
            assert!(
                (p - want).abs() <= 1e-9 * want.max(1e-300) + 1e-300,
                "{f} {d1} {d2}: {p} {want}"
            );
        }
        assert_eq!(f_upper_tail(0.0, 3.0, 10.0), 1.0);
        assert_eq!(f_upper_tail(f64::INFINITY, 3.0, 10.0), 0.0);
    }

    /// Two inputs (the first strongly coloured: AR(2) with poles 0.95 and
    /// 0.7 plus white noise, an ARMA process; the second white) into a two-output plant with slow modes and
    /// coloured output noise. `feedback`: the first input reacts to the
    /// first output within the sample (`-0.4 y1(t)`), the second to the
    /// second output's previous sample (`+0.8 y2(t - 1)`, against the
    /// plant's negative gain).
    fn plant(seed: u64, n: usize, feedback: bool) -> IoData {
        let mut rng = Rng::new(seed);
        let (mut u, mut y) = (DMatrix::zeros(n, 2), DMatrix::zeros(n, 2));
        let (mut r1, mut r1p, mut v1, mut v2) = (0.0, 0.0, 0.0, 0.0);
        let (mut x1, mut x2, mut x3) = (0.0, 0.0, 0.0);
        for t in 0..n {
            let r = 1.65 * r1 - 0.665 * r1p + rng.normal();
            (r1p, r1) = (r1, r);
            // Plus white noise: an ARMA input, no finite autoregression.
            let r = r + 2.0 * rng.normal();
            v1 = 0.9 * v1 + 0.3 * rng.normal();
            v2 = 0.5 * v2 + 0.3 * rng.normal();
            let y1 = x1 + 0.5 * x3 + v1;
            let y2 = x2 + v2;
            let (u1, u2) = if feedback {
                (
                    0.3 * r - 0.4 * y1,
                    rng.normal() + 0.8 * y[(t.max(1) - 1, 1)],
                )
            } else {
                (0.3 * r, rng.normal())
            };
            u[(t, 0)] = u1;
            u[(t, 1)] = u2;
            y[(t, 0)] = y1;
            y[(t, 1)] = y2;
            x1 = 0.95 * x1 + 0.2 * u1 + 0.1 * u2;
            x2 = 0.8 * x2 + 0.3 * u1 - 0.4 * u2;
            x3 = 0.98 * x3 + 0.05 * u2;
        }
        IoData::new(1.0, u, y).unwrap()
    }

    /// Open loop with a coloured input: no feedback at the stated level
    /// in 20 records (at most one false alarm allowed: the level is 0.01
    /// per record); with 2 lags (too few for the input's colour) the
    /// same records look like feedback. Closed loop: found in every record.
    #[test]
    fn open_loop_coloured_inputs_pass_and_closed_loop_is_found() {
        let mut alarms = 0;
        let mut faked = 0;
        for seed in 0..20 {
            let d = plant(seed, 3000, false);
            let r = feedback_test(&d, &FeedbackSettings::default()).unwrap();
            assert!(r.lags >= 20 && r.rows == 3000 - r.lags, "{r}");
            alarms += usize::from(r.feedback);
            let short = FeedbackSettings {
                lags: Some(2),
                ..Default::default()
            };
            faked += usize::from(feedback_test(&d, &short).unwrap().feedback);
            let c = feedback_test(&plant(seed, 3000, true), &FeedbackSettings::default()).unwrap();
            // u2 reacts to y2(t - 1): found; u1 reacts within the sample,
            // which the same-sample figure shows (the lagged test sees it
            // only through the plant's memory, here not always).
            assert!(c.feedback && c.inputs[1].feedback, "{c}");
            assert!(c.inputs[0].same_sample.p_value < 0.005, "{c}");
        }
        assert!(alarms <= 1, "{alarms} false alarms in 20 open-loop records");
        assert!(faked >= 15, "2 lags faked feedback in only {faked} of 20");
    }

    /// The estimation half of the DaISy steam generator (open loop): no
    /// feedback with the chosen lag count; with 2 lags u1 looks like
    /// feedback (F about 55: too few lags).
    #[test]
    fn steam_generator_shows_no_feedback() {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/daisy/steam_generator.csv");
        let cols = CsvColumns::new(&["u1", "u2", "u3", "u4"], &["y1", "y2", "y3", "y4"]);
        let (est, _) = IoData::read_csv(&path, &cols).unwrap().split(0.5).unwrap();
        let r = feedback_test(&est, &FeedbackSettings::default()).unwrap();
        assert!(!r.feedback, "{r}");
        assert!(r.inputs.iter().all(|i| i.lagged.f < 2.0), "{r}");
        let short = FeedbackSettings {
            lags: Some(2),
            ..Default::default()
        };
        let s = feedback_test(&est, &short).unwrap();
        assert!(s.feedback && s.inputs[0].lagged.f > 20.0, "{s}");
    }

    /// A short record lowers the lag count, a too short one and a
    /// constant input are errors, and so is a level outside (0, 1).
    #[test]
    fn short_records_and_bad_settings() {
        let d = plant(3, 300, true);
        let r = feedback_test(&d, &FeedbackSettings::default()).unwrap();
        assert!(r.lags < 20 && r.rows >= 5 * (4 * r.lags + 2), "{r}");
        let tiny = plant(3, 12, true);
        assert!(matches!(
            feedback_test(&tiny, &FeedbackSettings::default()),
            Err(SysidError::TooFewSamples { .. })
        ));
        let mut u = d.experiments()[0].u.clone();
        u.column_mut(1).fill(2.0);
        let flat = IoData::new(1.0, u, d.experiments()[0].y.clone()).unwrap();
        assert!(matches!(
            feedback_test(&flat, &FeedbackSettings::default()),
            Err(SysidError::ConstantInput { .. })
        ));
        let bad = FeedbackSettings {
            level: 1.0,
            ..Default::default()
        };
        assert!(matches!(
            feedback_test(&d, &bad),
            Err(SysidError::InvalidArgument(_))
        ));
    }
}
