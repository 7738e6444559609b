//! The tricopter's problems: the trim in the thesis's PWM convention, the
//! actuation (trim + move + throttle, saturated), and the thesis-sized and
//! larger problems.

use crate::condense::MpcProblem;
use crate::design::{InputBounds, MpcSettings, Weight, pwm};
use crate::error::MpcError;
use kestrel_core::formats::SsModel;
use kestrel_tricopter_model::{ESC_PWM_RANGE, Params, RateInputs, RateModelKind, SERVO_PWM_RANGE};

/// The hover trim of a 4-input tricopter model (`[motor 1, motor 2,
/// motor 3, servo]`) in the thesis's convention (7.2): motor offsets from
/// the common throttle and the servo offset from its centre.
///
/// A model's `u0` comes in one of two conventions, told apart by size:
/// the thesis's relative one (motor entries are offsets of tens of
/// microseconds, e.g. `[15.63, 0.85, -16.01, ...]`), or absolute pulses as
/// kestrel-tricopter-model writes them (motor entries near the hover
/// throttle, above 500 us). Absolute motor pulses are split into the hover
/// throttle (their mean) and offsets; an absolute servo pulse (above 500
/// us) is taken relative to its centre, 1500 us.
///
/// ```
/// use kestrel_mpc::TricopterTrim;
/// let t = TricopterTrim::from_u0(&[1490.0, 1500.0, 1510.0, 1520.0]).unwrap();
/// assert_eq!(t.hover_throttle, 1500.0);
/// assert_eq!(t.offsets, [-10.0, 0.0, 10.0, 20.0]);
/// // z = 0 at the hover throttle gives back the trim pulses.
/// assert_eq!(t.actuate(&[0.0; 4], 1500.0).unwrap().pwm, [1490.0, 1500.0, 1510.0, 1520.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TricopterTrim {
    /// The common throttle at hover (us); 0 when `u0` was relative.
    pub hover_throttle: f64,
    /// Offsets at hover: motors from the throttle, servo from 1500 us.
    pub offsets: [f64; 4],
}

/// Pulses sent to the aircraft for one input move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuation {
    /// `[pwm1, pwm2, pwm3, servo]` (us), inside the ESC and servo ranges.
    pub pwm: [f64; 4],
    /// Which pulses were clipped to their range.
    pub saturated: [bool; 4],
    /// The move actually applied (deviation from the trim after clipping),
    /// for the estimator's time update.
    pub applied: [f64; 4],
}

impl TricopterTrim {
    /// Reads the trim from a model's `u0` (see the type's documentation).
    pub fn from_u0(u0: &[f64]) -> Result<Self, MpcError> {
        if u0.len() != 4 {
            return Err(MpcError::dim(
                "tricopter u0",
                "4 entries [motor 1, motor 2, motor 3, servo]",
                format!("{} entries", u0.len()),
            ));
        }
        if u0.iter().any(|v| !v.is_finite()) {
            return Err(MpcError::NonFinite("tricopter u0".into()));
        }
        let absolute = u0[..3].iter().all(|&v| v > 500.0);
        let relative = u0[..3].iter().all(|&v| v.abs() <= 500.0);
        if !absolute && !relative {
            return Err(MpcError::setting(
                "tricopter u0",
                format!(
                    "motor trims {:?} mix absolute pulses (> 500 us) and offsets from the throttle",
                    &u0[..3]
                ),
            ));
        }
        let hover = if absolute {
            (u0[0] + u0[1] + u0[2]) / 3.0
        } else {
            0.0
        };
        let servo = if u0[3] > 500.0 {
            u0[3] - pwm::SERVO_CENTER
        } else {
            u0[3]
        };
        Ok(TricopterTrim {
            hover_throttle: hover,
            offsets: [u0[0] - hover, u0[1] - hover, u0[2] - hover, servo],
        })
    }

    /// The input bounds (6.5)-(6.7) around this trim.
    pub fn bounds(&self) -> InputBounds {
        // Only fails on a wrong length or non-finite trim, excluded by construction.
        InputBounds::tricopter_pwm(&self.offsets).unwrap_or_else(|_| {
            InputBounds::new(nalgebra::DVector::zeros(4), nalgebra::DVector::zeros(4))
        })
    }

    /// The pulses for the move `z` (deviation from the trim) at `throttle`:
    /// motors `throttle + offset_i + z_i`, servo `1500 + offset_4 + z_4`,
    /// each clipped to its range (ESC 1000-2000 us, servo 1200-1800 us).
    pub fn actuate(&self, z: &[f64], throttle: f64) -> Result<Actuation, MpcError> {
        if z.len() != 4 {
            return Err(MpcError::dim(
                "input move",
                "4 entries",
                format!("{}", z.len()),
            ));
        }
        if z.iter().any(|v| !v.is_finite()) || !throttle.is_finite() {
            return Err(MpcError::NonFinite("input move or throttle".into()));
        }
        let mut out = Actuation {
            pwm: [0.0; 4],
            saturated: [false; 4],
            applied: [0.0; 4],
        };
        for (i, zi) in z.iter().enumerate() {
            let (base, (lo, hi)) = if i < 3 {
                (throttle + self.offsets[i], ESC_PWM_RANGE)
            } else {
                (pwm::SERVO_CENTER + self.offsets[3], SERVO_PWM_RANGE)
            };
            let raw = base + zi;
            let c = raw.clamp(lo, hi);
            out.saturated[i] = c != raw;
            out.pwm[i] = c;
            out.applied[i] = c - base;
        }
        Ok(out)
    }
}

/// The two problem sizes of the issue.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ProblemSize {
    /// The thesis's: `N = 2`, `N_s = 1` (one block of two steps).
    Thesis,
    /// `N = 10`, blocks `[1, 1, 2, 6]`.
    Larger,
}

/// Default weights for the tricopter rate loop: `Q1 = 2000 I` on the rate
/// errors (rad/s) and `Q2 = 0.01 I` on the pulse deviations (us), so a
/// 1 rad/s error costs as much as about 450 us of pulse (tuned on the
/// default aircraft for a response close to the baseline PI).
pub fn default_weights() -> (Weight, Weight) {
    (Weight::Scalar(2000.0), Weight::Scalar(0.01))
}

impl ProblemSize {
    /// The settings of this size with the given weights and the LQ terminal weight.
    pub fn settings(self, q1: Weight, q2: Weight) -> MpcSettings {
        match self {
            ProblemSize::Thesis => MpcSettings::thesis(q1, q2),
            ProblemSize::Larger => MpcSettings::larger(q1, q2),
        }
    }
}

/// The physical design model (for comparison with [`identified_model`],
/// which is the default): the rates-plus-actuators linearisation of kestrel-tricopter-model's default
/// aircraft at hover (`[p, q, r, w1, w2, w3, alpha, alpha_dot]`, 8 states,
/// PWM inputs with absolute `u0`), discretised at 50 Hz.
pub fn design_model() -> Result<SsModel, MpcError> {
    kestrel_tricopter_model::rate_model_discrete(
        &Params::default(),
        RateModelKind::WithActuators,
        RateInputs::Pwm,
        0.02,
    )
    .map_err(|e| MpcError::setting("tricopter design model", e.to_string()))
}

/// The identified design model: `models/tricopter-blackbox-5.json` of
/// this repository (`kestrel.ss.v1`), the 5-state black-box rate model of
/// kestrel-tricopter-model's default aircraft identified as in section 7.4
/// (inputs `pwm1, pwm2, pwm3, servo` in us, outputs `p, q, r` in rad/s,
/// 50 Hz, operating point `u0`/`y0` in absolute pulses and rad/s), in the
/// form the MPC uses: a feed-through `D` (from a DC-matched reduction) is
/// moved behind one sample ([`delay_feedthrough`]). It is embedded at
/// compile time, so a re-identified model is picked up by the next build.
///
/// ```
/// let m = kestrel_mpc::identified_model().unwrap();
/// assert_eq!((m.nu(), m.ny()), (4, 3));
/// assert!(m.d.iter().all(|v| *v == 0.0) && m.u0.is_some());
/// ```
pub fn identified_model() -> Result<SsModel, MpcError> {
    delay_feedthrough(&SsModel::from_json_str(IDENTIFIED_MODEL_JSON)?)
}

/// A model with feed-through `y_k = C x_k + D u_k` as a strictly proper
/// one for the MPC: `D` acts one sample later, through `nu` added states
/// holding the previous input (`x_u+ = u`, `y = C x + D x_u`); a model
/// with `D = 0` is returned unchanged.
///
/// In the control loop the gyro sample `y_k` is taken before `u_k` is
/// computed and applied, so `D u_k` cannot show before `k + 1` anyway;
/// kestrel-kalman's filter uses `D` on the previous input the same way.
///
/// ```
/// use kestrel_core::formats::SsModel;
/// use nalgebra::dmatrix;
/// let m = SsModel::new(0.1, dmatrix![0.5], dmatrix![1.0], dmatrix![1.0], dmatrix![0.2]).unwrap();
/// let s = kestrel_mpc::delay_feedthrough(&m).unwrap();
/// assert_eq!(s.nx(), 2);
/// assert_eq!(s.c, dmatrix![1.0, 0.2]);
/// assert_eq!(s.d, dmatrix![0.0]);
/// ```
pub fn delay_feedthrough(model: &SsModel) -> Result<SsModel, MpcError> {
    if model.d.iter().all(|v| *v == 0.0) {
        return Ok(model.clone());
    }
    let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
    let n = nx + nu;
    let mut a = nalgebra::DMatrix::zeros(n, n);
    a.view_mut((0, 0), (nx, nx)).copy_from(&model.a);
    let mut b = nalgebra::DMatrix::zeros(n, nu);
    b.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    b.view_mut((nx, 0), (nu, nu))
        .copy_from(&nalgebra::DMatrix::identity(nu, nu));
    let mut c = nalgebra::DMatrix::zeros(ny, n);
    c.view_mut((0, 0), (ny, nx)).copy_from(&model.c);
    c.view_mut((0, nx), (ny, nu)).copy_from(&model.d);
    let mut out = SsModel::new(model.ts, a, b, c, nalgebra::DMatrix::zeros(ny, nu))?;
    out.u0 = model.u0.clone();
    out.y0 = model.y0.clone();
    out.inputs = model.inputs.clone();
    out.outputs = model.outputs.clone();
    Ok(out)
}

/// The text of [`identified_model`] (`models/tricopter-blackbox-5.json`).
pub const IDENTIFIED_MODEL_JSON: &str = include_str!("../../../models/tricopter-blackbox-5.json");

/// The tricopter problem of a given size for a 4-input model with `u0`
/// (bounds from [`TricopterTrim::from_u0`]); a model without `u0` is taken
/// to be linearised at zero offsets.
///
/// ```
/// use kestrel_mpc::{ProblemSize, default_weights, design_model, tricopter_problem};
/// let model = design_model().unwrap();
/// let (q1, q2) = default_weights();
/// let p = tricopter_problem(&model, ProblemSize::Larger, q1, q2).unwrap();
/// assert_eq!((p.n(), p.m(), p.p()), (16, 32, model.nx() + 4));
/// ```
pub fn tricopter_problem(
    model: &SsModel,
    size: ProblemSize,
    q1: Weight,
    q2: Weight,
) -> Result<MpcProblem, MpcError> {
    let trim = tricopter_trim(model)?;
    MpcProblem::build(model, &trim.bounds(), &size.settings(q1, q2))
}

/// The trim of a 4-input model from its `u0` (zeros when absent).
pub fn tricopter_trim(model: &SsModel) -> Result<TricopterTrim, MpcError> {
    if model.nu() != 4 {
        return Err(MpcError::dim(
            "tricopter model inputs",
            "4 inputs [motor 1, motor 2, motor 3, servo]",
            format!("{} inputs", model.nu()),
        ));
    }
    match &model.u0 {
        Some(u0) => TricopterTrim::from_u0(u0.as_slice()),
        None => TricopterTrim::from_u0(&[0.0; 4]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trim_conventions_and_actuation() {
        // Thesis (7.2) relative offsets; servo given absolute.
        let t = TricopterTrim::from_u0(&[15.63, 0.85, -16.01, 1467.7]).unwrap();
        assert_eq!(t.hover_throttle, 0.0);
        assert!((t.offsets[3] - (1467.7 - 1500.0)).abs() < 1e-12);
        let a = t.actuate(&[0.0, 100.0, -2000.0, 400.0], 1500.0).unwrap();
        assert!((a.pwm[0] - 1515.63).abs() < 1e-9 && !a.saturated[0]);
        assert_eq!(a.pwm[2], 1000.0);
        assert!(a.saturated[2] && a.saturated[3]);
        assert_eq!(a.pwm[3], 1800.0);
        assert!((a.applied[2] - (1000.0 - 1500.0 + 16.01)).abs() < 1e-9);
        // Mixed conventions and bad lengths are errors.
        assert!(TricopterTrim::from_u0(&[1500.0, 0.0, 0.0, 0.0]).is_err());
        assert!(TricopterTrim::from_u0(&[0.0; 3]).is_err());
        assert!(t.actuate(&[0.0; 4], f64::NAN).is_err());
    }

    #[test]
    fn bounds_match_actuator_ranges() {
        // The QP bounds at any throttle are exactly the pulses' ranges.
        let model = design_model().unwrap();
        let trim = tricopter_trim(&model).unwrap();
        let b = trim.bounds();
        for th in [1100.0, 1450.0, 1900.0] {
            let at = b.at(th);
            let lo = trim.actuate(at.lower.as_slice(), th).unwrap();
            let hi = trim.actuate(at.upper.as_slice(), th).unwrap();
            for i in 0..3 {
                assert!((lo.pwm[i] - 1000.0).abs() < 1e-9 && (hi.pwm[i] - 2000.0).abs() < 1e-9);
            }
            assert!((lo.pwm[3] - 1200.0).abs() < 1e-9 && (hi.pwm[3] - 1800.0).abs() < 1e-9);
            assert!((&at.upper - nalgebra::DVector::from_column_slice(&hi.applied)).amax() < 1e-9);
        }
    }
}
