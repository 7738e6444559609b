//! The two problem sizes of the issue, the default weights, and the
//! tricopter problem of a 4-input model.

use crate::constants::{PULSE_WEIGHT, RATE_WEIGHT};
use crate::error::TricopterError;
use crate::problems::trim::TricopterTrim;
use kestrel_core::formats::SsModel;
use kestrel_mpc::{Blocking, MpcProblem, MpcSettings, Terminal, Weight};

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
    (Weight::Scalar(RATE_WEIGHT), Weight::Scalar(PULSE_WEIGHT))
}

impl ProblemSize {
    /// The settings of this size with the given weights and the LQ terminal
    /// weight: the thesis-sized problem of section 7.6 is `N = 2`, `N_s = 1`
    /// (one block of two steps), the larger `N = 10`, blocks `[1, 1, 2, 6]`.
    ///
    /// ```
    /// use kestrel_tricopter::{ProblemSize, default_weights};
    /// let (q1, q2) = default_weights();
    /// let s = ProblemSize::Larger.settings(q1, q2);
    /// assert_eq!((s.horizon, s.blocking().lengths()), (10, &[1, 1, 2, 6][..]));
    /// ```
    pub fn settings(self, q1: Weight, q2: Weight) -> MpcSettings {
        let (horizon, blocks) = match self {
            ProblemSize::Thesis => (2, vec![2]),
            ProblemSize::Larger => (10, vec![1, 1, 2, 6]),
        };
        MpcSettings {
            horizon,
            // The lengths are positive, so `Blocking::new` accepts them.
            blocking: Blocking::new(blocks).ok(),
            q1,
            q2,
            terminal: Terminal::Lq,
            ..MpcSettings::default()
        }
    }
}

/// The tricopter problem of a given size for a 4-input model with `u0`
/// (bounds from [`TricopterTrim::from_u0`]); a model without `u0` is taken
/// to be linearised at zero offsets.
///
/// ```
/// use kestrel_tricopter::{ProblemSize, default_weights, design_model, tricopter_problem};
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
) -> Result<MpcProblem, TricopterError> {
    let trim = tricopter_trim(model)?;
    Ok(MpcProblem::build(
        model,
        &trim.constrain(size.settings(q1, q2)),
    )?)
}

/// The trim of a 4-input model from its `u0` (zeros when absent).
pub fn tricopter_trim(model: &SsModel) -> Result<TricopterTrim, TricopterError> {
    if model.nu() != 4 {
        return Err(TricopterError::dim(
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
    use crate::problems::design_model;

    #[test]
    fn bounds_match_actuator_ranges() {
        // The QP bounds at any throttle are exactly the pulses' ranges.
        let model = design_model().unwrap();
        let trim = tricopter_trim(&model).unwrap();
        let b = trim.bounds();
        for th in [1100.0, 1450.0, 1900.0] {
            let at = b.at(&[th]);
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
