//! A high-order ARX (or ARMAX) model reduced by balanced truncation: the
//! "high-order VARX plus reduction" closed-loop-consistent start.

use super::stabilise::stabilise_a;
use crate::armax::{ArmaxSettings, armax};
use crate::arx::{ArxSettings, arx};
use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::model::InnovationModel;
use crate::n4sid::suggest_order;
use crate::pem::{Focus, PemSettings, pem};
use crate::reduce::{BalredSettings, ReductionMethod, balred};

/// The largest realisation [`arx_reduction`] reduces (`ny x lags`
/// states): its balanced truncation costs a few times `n^3`.
pub const MAX_REALISATION: usize = 240;

/// Settings of [`arx_reduction`].
#[derive(Clone, Debug, PartialEq)]
pub struct ArxReductionSettings {
    /// Model order; `None` takes the order suggested by the largest gap
    /// of the Hankel singular values (up to
    /// [`max_order`](Self::max_order)).
    pub order: Option<usize>,
    /// Largest order considered when suggesting one.
    pub max_order: usize,
    /// Lags `l` of the ARX (`na = nb = l`): its realisation has `ny l`
    /// states (at most [`MAX_REALISATION`]), so the order must not exceed
    /// that.
    pub lags: usize,
    /// Noise lags `nc`: 0 fits an ARX; more fits an ARMAX
    /// ([`armax`](crate::armax()), Hannan-Rissanen with pseudo-linear
    /// passes) with `na = nb = lags` and `nc = noise_lags <= lags`, whose
    /// moving-average noise model lets few lags (an ARMAX of the model's
    /// own order: `order = ny lags`, no reduction) describe coloured
    /// noise.
    pub noise_lags: usize,
    /// Estimate a feed-through `D` (the ARX then includes `u(t)`).
    pub feedthrough: bool,
    /// Modes of the ARX realisation outside `|z| <= max_radius` are moved
    /// onto that circle before the reduction ([`stabilise_a`]), so that
    /// the result can start [`pem`](crate::pem()).
    pub max_radius: f64,
}

impl Default for ArxReductionSettings {
    /// Order suggested up to 10, an ARX of 10 lags, no `D`, `A` inside
    /// 0.999.
    fn default() -> Self {
        ArxReductionSettings {
            order: None,
            max_order: 10,
            lags: 10,
            noise_lags: 0,
            feedthrough: false,
            max_radius: 0.999,
        }
    }
}

/// Result of [`arx_reduction`].
#[derive(Clone, Debug, PartialEq)]
pub struct ArxReduction {
    /// The reduced innovation model, `K` refitted to the reduced
    /// dynamics.
    pub model: InnovationModel,
    /// Hankel singular values of the (stabilised) ARX realisation with
    /// its noise channels, descending.
    pub hankel_singular_values: Vec<f64>,
    /// The order suggested by their largest gap.
    pub suggested_order: usize,
    /// The order used.
    pub order: usize,
    /// The ARX (ARMAX) lags used.
    pub lags: usize,
    /// Spectral radius of the ARX realisation's `A` before any move onto
    /// [`ArxReductionSettings::max_radius`].
    pub radius_estimated: f64,
}

/// Identification by a high-order ARX model reduced to a low order, a
/// closed-loop-consistent alternative to N4SID ("high-order VARX plus
/// model reduction"; Ljung, *System Identification*, 2nd ed., sections
/// 10.4 and 13.5; Zhu's asymptotic method works the same way).
///
/// 1. An ARX model with `l` lags ([`arx`](crate::arx())) is fitted by
///    least squares: consistent in closed loop, because the innovation is
///    uncorrelated with the past the regression uses, and unbiased as `l`
///    grows (the ARX is then the model's whole one-step predictor); with
///    [`noise_lags`](ArxReductionSettings::noise_lags) an ARMAX instead;
/// 2. its realisation ([`ArxModel::to_innovation_model`](crate::ArxModel::to_innovation_model),
///    `ny l` states) has any mode outside `max_radius` moved inside
///    ([`stabilise_a`]);
/// 3. balanced truncation ([`balred`](crate::balred()), the noise
///    channels `K` balanced with the inputs) keeps `order` states;
/// 4. the noise model `K` is refitted to the reduced dynamics by one-step
///    prediction errors with `A`, `B`, `C`, `D` fixed
///    ([`PemSettings::fixed_dynamics`]).
///
/// The result is a start for [`pem`](crate::pem()); on the real flight
/// logs at 50 Hz it gave the best one-step fits at orders 6-8 of the
/// starts compared (`docs/sysid.md`, "The one-step gap to ARX").
///
/// ```
/// use kestrel_sysid::{arx_reduction, synthetic, ArxReductionSettings};
/// let truth = synthetic::random_model(3, 2, 2, 1, 0.9);
/// let data = synthetic::simulate(&truth, 3000, 0.1, 7).unwrap();
/// let s = ArxReductionSettings { order: Some(3), lags: 8, ..Default::default() };
/// let r = arx_reduction(&data, &s).unwrap();
/// assert_eq!((r.order, r.model.nx(), r.lags), (3, 3, 8));
/// assert!(r.model.radius_a() < 1.0);
/// ```
pub fn arx_reduction(data: &IoData, settings: &ArxReductionSettings) -> Result<ArxReduction> {
    let s = settings;
    if s.lags == 0 {
        return Err(SysidError::invalid("the ARX needs at least one lag"));
    }
    if s.noise_lags > s.lags {
        return Err(SysidError::invalid(format!(
            "noise lags {} exceed the lags {}: the realisation would not have the ny x lags states the order is checked against",
            s.noise_lags, s.lags
        )));
    }
    if s.order == Some(0) || s.max_order == 0 {
        return Err(SysidError::invalid("the model order must be at least 1"));
    }
    let kind = if s.noise_lags == 0 { "ARX" } else { "ARMAX" };
    let nx = data.ny() * s.lags;
    if nx > MAX_REALISATION {
        return Err(SysidError::invalid(format!(
            "{} lags give a {kind} realisation of {nx} states ({} outputs x lags), above the {MAX_REALISATION} that the balanced truncation handles in seconds; use fewer lags",
            s.lags,
            data.ny()
        )));
    }
    if let Some(n) = s.order.filter(|&n| n > nx) {
        return Err(SysidError::invalid(format!(
            "order {n} exceeds the {nx} states of the {kind} realisation ({} outputs x {} lags); raise the lags",
            data.ny(),
            s.lags
        )));
    }
    // nk = 0 with one more input lag keeps the largest lag at `lags`.
    let (nb, nk) = if s.feedthrough {
        (s.lags + 1, 0)
    } else {
        (s.lags, 1)
    };
    let full = if s.noise_lags == 0 {
        let settings = ArxSettings { na: s.lags, nb, nk };
        arx(data, &settings)?.to_innovation_model()?
    } else {
        let settings = ArmaxSettings {
            na: s.lags,
            nb,
            nc: s.noise_lags,
            nk,
            ..Default::default()
        };
        armax(data, &settings)?.to_innovation_model()?
    };
    let radius_estimated = full.radius_a();
    let stable = stabilise_a(&full, s.max_radius)?;
    let reduction = BalredSettings {
        method: ReductionMethod::Truncate,
        include_noise: true,
    };
    let balanced = balred(&stable, stable.nx(), &reduction)?;
    let hsv = balanced.hankel_singular_values;
    let suggested_order = suggest_order(&hsv, s.max_order.min(stable.nx()));
    let order = s.order.unwrap_or(suggested_order);
    let reduced = if order == stable.nx() {
        balanced.model
    } else {
        balred(&stable, order, &reduction)?.model
    };
    let noise = PemSettings {
        focus: Focus::Prediction,
        fixed_dynamics: true,
        ..Default::default()
    };
    let model = pem(data, &reduced, &noise)?.model;
    Ok(ArxReduction {
        model,
        hankel_singular_values: hsv,
        suggested_order,
        order,
        lags: s.lags,
        radius_estimated,
    })
}
