//! Input delay estimation from the significance of ARX coefficients.

use crate::arx::{ArxSettings, NormalEquations, solve_normal_equations};
use crate::data::IoData;
use crate::error::{Result, SysidError};

/// Settings of [`estimate_delay`].
#[derive(Clone, Debug, PartialEq)]
pub struct DelaySettings {
    /// Largest delay considered, in samples.
    pub max_delay: usize,
    /// Output lags `na` of the ARX model the test runs on.
    pub na: usize,
    /// Input lags beyond `max_delay` in that model (so that the input's
    /// response after the delay is modelled too).
    pub extra_lags: usize,
    /// Significance level of the test of one lag's coefficients (the
    /// probability that a lag without effect is declared significant).
    pub significance: f64,
}

impl Default for DelaySettings {
    /// Delays up to 10 samples, `na = 4`, 4 extra input lags, level 0.001.
    fn default() -> Self {
        DelaySettings {
            max_delay: 10,
            na: 4,
            extra_lags: 4,
            significance: 1e-3,
        }
    }
}

/// Result of [`estimate_delay`].
#[derive(Clone, Debug, PartialEq)]
pub struct DelayEstimate {
    /// Per input: the smallest lag whose coefficients are significant,
    /// `None` when none up to `max_delay` is.
    pub delays: Vec<Option<usize>>,
    /// Per input, per lag `0..=max_delay`: the Wald statistic of the
    /// `ny` coefficients of that input at that lag (chi-squared with `ny`
    /// degrees of freedom when the lag has no effect).
    pub statistics: Vec<Vec<f64>>,
    /// The statistic's threshold at the chosen significance.
    pub threshold: f64,
}

/// Estimates the dead time of every input (MATLAB's `delayest`, for
/// MIMO data): an ARX model with `na` output lags and input lags
/// `0..=max_delay + extra_lags` (`nk = 0`) is fitted by least squares,
/// and for every input and lag the Wald statistic
/// `sum_o theta_o^2 / var(theta_o)` of its `ny` coefficients is
/// compared with the chi-squared quantile of `ny` degrees of freedom at
/// the given significance; the delay is the first significant lag.
///
/// On closed-loop data whose inputs react to the outputs within one
/// sample (a controller faster than the sample rate, or cell means of
/// fast signals), the feedback makes lag 0 significant whatever the
/// plant's delay: read the statistics, not only the delays, there.
///
/// ```
/// use kestrel_sysid::{estimate_delay, synthetic, DelaySettings, InnovationModel};
/// # use nalgebra::DMatrix;
/// // y(t) = 0.5 y(t-1) + u(t-3) + e(t)
/// let m = InnovationModel::new(
///     1.0,
///     DMatrix::from_row_slice(3, 3, &[0.5, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
///     DMatrix::from_row_slice(3, 1, &[0.0, 0.0, 1.0]),
///     DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]),
///     DMatrix::zeros(1, 1),
///     DMatrix::zeros(3, 1),
/// )
/// .unwrap();
/// let data = synthetic::simulate(&m, 2000, 0.1, 1).unwrap();
/// let d = estimate_delay(&data, &DelaySettings::default()).unwrap();
/// assert_eq!(d.delays, vec![Some(3)]);
/// ```
pub fn estimate_delay(data: &IoData, settings: &DelaySettings) -> Result<DelayEstimate> {
    let s = settings;
    if !(s.significance > 0.0 && s.significance < 0.5) {
        return Err(SysidError::invalid(format!(
            "delay test significance must lie in (0, 0.5), found {}",
            s.significance
        )));
    }
    if data.nu() == 0 {
        return Err(SysidError::invalid(
            "delay estimation needs at least one input",
        ));
    }
    let arx_settings = ArxSettings {
        na: s.na,
        nb: s.max_delay + 1 + s.extra_lags,
        nk: 0,
    };
    let (nu, ny) = (data.nu(), data.ny());
    let ne = NormalEquations::of(data, &arx_settings)?;
    let theta = solve_normal_equations(&ne.gram, &ne.cross)?;
    let p = ne.gram.nrows();
    let dof = ne.rows.saturating_sub(p).max(1) as f64;
    let resid = &ne.yy - theta.tr_mul(&ne.cross);
    // Diagonal of the inverse normal-equation matrix, by Cholesky.
    let chol =
        ne.gram.clone().cholesky().ok_or_else(|| {
            SysidError::Numerical("normal equations not positive definite".into())
        })?;
    let ginv = chol.inverse();
    let threshold = chi2_quantile(ny as f64, 1.0 - s.significance);
    let mut delays = Vec::with_capacity(nu);
    let mut statistics = Vec::with_capacity(nu);
    for q in 0..nu {
        let stats: Vec<f64> = (0..=s.max_delay)
            .map(|lag| {
                let j = ny * s.na + lag * nu + q;
                (0..ny)
                    .map(|o| {
                        let var = resid[(o, o)] / dof * ginv[(j, j)];
                        theta[(j, o)].powi(2) / var.max(f64::MIN_POSITIVE)
                    })
                    .sum()
            })
            .collect();
        delays.push(stats.iter().position(|w| *w > threshold));
        statistics.push(stats);
    }
    Ok(DelayEstimate {
        delays,
        statistics,
        threshold,
    })
}

/// The `prob` quantile of the chi-squared distribution with `k` degrees
/// of freedom ([`statrs`]'s inverse CDF, as the feedback test's F tail).
fn chi2_quantile(k: f64, prob: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(k).map_or(f64::NAN, |d| d.inverse_cdf(prob))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::Rng;
    use nalgebra::DMatrix;

    /// Two inputs with delays 3 and 1 into two coupled outputs.
    fn delayed_data(n: usize, seed: u64) -> IoData {
        let mut rng = Rng::new(seed);
        let u = rng.normal_matrix(n, 2);
        let mut y = DMatrix::zeros(n, 2);
        for t in 4..n {
            y[(t, 0)] = 0.6 * y[(t - 1, 0)] + 0.8 * u[(t - 3, 0)] + 0.3 * u[(t - 4, 0)];
            y[(t, 1)] = 0.5 * y[(t - 1, 1)] + 0.2 * y[(t - 1, 0)] - 0.7 * u[(t - 1, 1)];
            y[(t, 0)] += 0.2 * rng.normal();
            y[(t, 1)] += 0.2 * rng.normal();
        }
        IoData::new(1.0, u, y).unwrap()
    }

    #[test]
    fn recovers_known_delays() {
        for seed in 1..=5 {
            let d = estimate_delay(&delayed_data(3000, seed), &DelaySettings::default()).unwrap();
            assert_eq!(d.delays, vec![Some(3), Some(1)], "{:?}", d.statistics);
            // Below the delay the statistics are chi-squared(2) sized.
            assert!(d.statistics[0][..3].iter().all(|w| *w < d.threshold));
        }
    }

    #[test]
    fn quantiles_match_tables() {
        // Chi-squared tables (Abramowitz and Stegun, table 26.8).
        for (k, p, table) in [
            (3.0, 0.999, 16.266),
            (1.0, 0.95, 3.841),
            (6.0, 0.999, 22.458),
            (2.0, 0.99, 9.210),
        ] {
            let q = chi2_quantile(k, p);
            assert!((q - table).abs() < 1e-3, "{k} {p}: {q} vs {table}");
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let data = delayed_data(40, 1);
        // 2 * 4 + 2 * 15 = 38 parameters per output on 40 samples.
        assert!(matches!(
            estimate_delay(&data, &DelaySettings::default()),
            Err(SysidError::TooFewSamples { .. })
        ));
        let e = &delayed_data(500, 2).experiments()[0].clone();
        let flat = IoData::new(1.0, DMatrix::zeros(500, 2), e.y.clone()).unwrap();
        assert!(matches!(
            estimate_delay(&flat, &DelaySettings::default()),
            Err(SysidError::ConstantInput { .. })
        ));
        let bad = DelaySettings {
            significance: 0.0,
            ..Default::default()
        };
        assert!(estimate_delay(&delayed_data(500, 2), &bad).is_err());
    }
}
