//! The reduced rate-only models of the thesis (7.7) and appendix C, and the
//! grey-box parameter vector they depend on.
//!
//! Both models are exact sub-blocks of the full linearisation at hover: the
//! body-rate equations (3.19) do not depend on position, velocity or
//! attitude, so nothing is neglected by cutting those states away.
//!
//! - [`RateModelKind::Rates`] keeps the states `[p, q, r]`, the motors and servo
//!   taken as static (`w = w_ss(pwm)`, `alpha = alpha_cmd(pwm)`), as in
//!   (7.7); at hover `A = 0` (the thesis's `-1e-9` diagonal is not needed).
//! - [`RateModelKind::WithActuators`] keeps the states
//!   `[p, q, r, w1, w2, w3, alpha, alpha_dot]`, as in (C.1)-(C.3). One
//!   difference to the printed (C.1): the servo is a position servo, so
//!   `a_{8,7} = -wn^2` is non-zero (C.1 models it as the open-loop DC motor
//!   (3.6), an integrator).
//!
//! Inputs are the four pulses (us) as deviations from the hover trim
//! (`u0` of the model); outputs `[p, q, r]` (rad/s). With
//! [`RateInputs::Virtual`] the inputs are the mixer's `[U_r, U_p, U_y]`
//! instead (the black-box *virtual* model (3.30)).

use crate::error::ModelError;
use crate::mixer::MIX_MATRIX;
use crate::model::{Tricopter, idx};
use crate::params::Params;
use crate::trim::Trim;
use kestrel_core::formats::SsModel;
use nalgebra::{DMatrix, DVector};

/// Which states the reduced rate model keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RateModelKind {
    /// `[p, q, r]` only, actuators static (thesis (7.7)).
    Rates,
    /// `[p, q, r, w1, w2, w3, alpha, alpha_dot]` (thesis appendix C).
    WithActuators,
}

/// Which inputs the reduced rate model takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RateInputs {
    /// `[pwm1, pwm2, pwm3, servo]` (us), the black-box model (3.26).
    Pwm,
    /// `[U_r, U_p, U_y]` (us) of the mixer, the black-box virtual model (3.30).
    Virtual,
}

/// The physical parameters the linearised rate model depends on: the
/// grey-box parameter vector for identification.
///
/// ```
/// use kestrel_tricopter_model::{GreyBoxParams, Params, RateInputs, RateModelKind, grey_box_rate_model};
/// let base = Params::default();
/// let mut g = GreyBoxParams::from_params(&base);
/// assert_eq!(GreyBoxParams::NAMES[0], "ixx");
/// g.set(0, 0.05).unwrap();                       // a heavier roll inertia
/// let m = grey_box_rate_model(&g, &base, RateModelKind::WithActuators, RateInputs::Pwm).unwrap();
/// assert_eq!((m.a.nrows(), m.b.ncols(), m.c.nrows()), (8, 4, 3));
/// let d = m.c2d(0.02).unwrap();                   // the thesis's 50 Hz
/// assert_eq!(d.ts, 0.02);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GreyBoxParams {
    /// `I_xx` (kg m^2).
    pub ixx: f64,
    /// `I_yy` (kg m^2).
    pub iyy: f64,
    /// `I_zz` (kg m^2).
    pub izz: f64,
    /// Thrust constant `k_t` (N s^2/rad^2).
    pub k_t: f64,
    /// Drag constant `k_tau` (N m s^2/rad^2).
    pub k_tau: f64,
    /// Motor time constant (s).
    pub motor_tau: f64,
    /// Servo natural frequency (rad/s).
    pub servo_wn: f64,
    /// Servo damping ratio.
    pub servo_zeta: f64,
}

impl GreyBoxParams {
    /// Number of parameters.
    pub const LEN: usize = 8;
    /// Parameter names, in vector order (the field names).
    pub const NAMES: [&'static str; 8] = [
        "ixx",
        "iyy",
        "izz",
        "k_t",
        "k_tau",
        "motor_tau",
        "servo_wn",
        "servo_zeta",
    ];

    /// The grey-box parameters of a full parameter set.
    pub fn from_params(p: &Params) -> Self {
        GreyBoxParams {
            ixx: p.ixx,
            iyy: p.iyy,
            izz: p.izz,
            k_t: p.k_t,
            k_tau: p.k_tau,
            motor_tau: p.motor_tau,
            servo_wn: p.servo_wn,
            servo_zeta: p.servo_zeta,
        }
    }

    /// The thesis's initial guess (Table 7.1 with the default actuators).
    pub fn thesis_initial_guess() -> Self {
        Self::from_params(&Params::thesis_table_7_1())
    }

    /// `base` with these parameters substituted (not validated).
    pub fn apply(&self, base: &Params) -> Params {
        Params {
            ixx: self.ixx,
            iyy: self.iyy,
            izz: self.izz,
            k_t: self.k_t,
            k_tau: self.k_tau,
            motor_tau: self.motor_tau,
            servo_wn: self.servo_wn,
            servo_zeta: self.servo_zeta,
            ..*base
        }
    }

    /// The parameters as a vector, in [`GreyBoxParams::NAMES`] order.
    pub fn to_array(&self) -> [f64; 8] {
        [
            self.ixx,
            self.iyy,
            self.izz,
            self.k_t,
            self.k_tau,
            self.motor_tau,
            self.servo_wn,
            self.servo_zeta,
        ]
    }

    /// Parameters from a vector in [`GreyBoxParams::NAMES`] order.
    pub fn from_array(v: &[f64; 8]) -> Self {
        GreyBoxParams {
            ixx: v[0],
            iyy: v[1],
            izz: v[2],
            k_t: v[3],
            k_tau: v[4],
            motor_tau: v[5],
            servo_wn: v[6],
            servo_zeta: v[7],
        }
    }

    /// Parameter `i` (see [`GreyBoxParams::NAMES`]).
    pub fn get(&self, i: usize) -> Result<f64, ModelError> {
        self.to_array()
            .get(i)
            .copied()
            .ok_or_else(|| Self::bad_index(i))
    }

    /// Sets parameter `i` (see [`GreyBoxParams::NAMES`]).
    pub fn set(&mut self, i: usize, value: f64) -> Result<(), ModelError> {
        let mut v = self.to_array();
        *v.get_mut(i).ok_or_else(|| Self::bad_index(i))? = value;
        *self = Self::from_array(&v);
        Ok(())
    }

    /// Index of a parameter by name.
    pub fn index_of(name: &str) -> Option<usize> {
        Self::NAMES.iter().position(|n| *n == name)
    }

    fn bad_index(i: usize) -> ModelError {
        ModelError::InvalidSetting {
            name: "grey-box parameter index",
            reason: format!("{i} is not below {}", Self::LEN),
        }
    }
}

/// The continuous-time reduced rate model of `params` at its hover trim.
///
/// The returned `SsModel` has `ts = 0`, `u0` = the trim pulses (or zero
/// virtual inputs), `y0 = 0`, `x0 = 0` (deviation states) and names.
pub fn rate_model(
    params: &Params,
    kind: RateModelKind,
    inputs: RateInputs,
) -> Result<SsModel, ModelError> {
    let model = Tricopter::new(*params)?;
    let trim = model.trim_hover()?;
    rate_model_at(&model, &trim, kind, inputs)
}

/// [`rate_model`] for `base` with the grey-box parameters `g` substituted
/// (validated, then re-trimmed): the map sysid fits.
pub fn grey_box_rate_model(
    g: &GreyBoxParams,
    base: &Params,
    kind: RateModelKind,
    inputs: RateInputs,
) -> Result<SsModel, ModelError> {
    rate_model(&g.apply(base), kind, inputs)
}

/// The reduced rate model of `model` linearised at `trim`.
pub fn rate_model_at(
    model: &Tricopter,
    trim: &Trim,
    kind: RateModelKind,
    inputs: RateInputs,
) -> Result<SsModel, ModelError> {
    let p = model.params();
    let lin = model.linearize(&trim.state, &trim.input);
    let rates = [idx::P, idx::Q, idx::R];
    let states: Vec<usize> = match kind {
        RateModelKind::Rates => rates.to_vec(),
        RateModelKind::WithActuators => vec![
            idx::P,
            idx::Q,
            idx::R,
            idx::W1,
            idx::W2,
            idx::W3,
            idx::ALPHA,
            idx::ALPHA_DOT,
        ],
    };
    let n = states.len();
    let a = DMatrix::from_fn(n, n, |i, j| lin.a[(states[i], states[j])]);
    let b_pwm = match kind {
        RateModelKind::WithActuators => DMatrix::from_fn(n, 4, |i, j| lin.b[(states[i], j)]),
        RateModelKind::Rates => {
            // Static actuators: d(rate')/d(pwm) = d(rate')/d(w, alpha) * d(w, alpha)/d(pwm).
            let gain = [
                p.omega_max * 1e-3,
                p.omega_max * 1e-3,
                p.omega_max * 1e-3,
                p.servo_gain,
            ];
            let act = [idx::W1, idx::W2, idx::W3, idx::ALPHA];
            DMatrix::from_fn(n, 4, |i, j| lin.a[(states[i], act[j])] * gain[j])
        }
    };
    let (b, u0, input_names): (DMatrix<f64>, DVector<f64>, Vec<&str>) = match inputs {
        RateInputs::Pwm => (
            b_pwm,
            DVector::from_column_slice(&trim.input),
            vec!["pwm1", "pwm2", "pwm3", "servo"],
        ),
        RateInputs::Virtual => {
            let mix = DMatrix::from_fn(4, 3, |i, j| MIX_MATRIX[i][j]);
            (
                b_pwm * mix,
                DVector::zeros(3),
                vec!["u_roll", "u_pitch", "u_yaw"],
            )
        }
    };
    let c = DMatrix::from_fn(3, n, |i, j| if i == j { 1.0 } else { 0.0 });
    let d = DMatrix::zeros(3, b.ncols());
    let mut m = SsModel::new(0.0, a, b, c, d)?;
    m.u0 = Some(u0);
    m.y0 = Some(DVector::zeros(3));
    m.x0 = Some(DVector::zeros(n));
    m.inputs = Some(input_names.iter().map(|s| s.to_string()).collect());
    m.outputs = Some(vec!["p".into(), "q".into(), "r".into()]);
    m.validate()?;
    Ok(m)
}

/// The reduced rate model discretised with zero-order hold (kestrel-core's
/// `c2d`) at sample time `ts` (0.02 s for the thesis's 50 Hz).
pub fn rate_model_discrete(
    params: &Params,
    kind: RateModelKind,
    inputs: RateInputs,
    ts: f64,
) -> Result<SsModel, ModelError> {
    Ok(rate_model(params, kind, inputs)?.c2d(ts)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(m: &DMatrix<f64>) -> Vec<Vec<bool>> {
        (0..m.nrows())
            .map(|i| (0..m.ncols()).map(|j| m[(i, j)].abs() > 1e-12).collect())
            .collect()
    }

    #[test]
    fn rates_model_zero_pattern_matches_7_7() {
        let m = rate_model(&Params::default(), RateModelKind::Rates, RateInputs::Pwm).unwrap();
        // (7.7): A = 0 at hover; B = [0 b b 0; b b b b; b b b b].
        assert!(m.a.iter().all(|v| *v == 0.0));
        let want = vec![
            vec![false, true, true, false],
            vec![true, true, true, true],
            vec![true, true, true, true],
        ];
        assert_eq!(pattern(&m.b), want);
        // Roll: the front motors act with opposite signs (b_{10,2} = -b_{10,3} at symmetric trim).
        assert!(m.b[(0, 1)] > 0.0 && m.b[(0, 2)] < 0.0);
        assert!((m.b[(0, 1)] + m.b[(0, 2)]).abs() < 1e-9 * m.b[(0, 1)].abs());
    }

    #[test]
    fn actuator_model_zero_pattern_matches_appendix_c() {
        let m = rate_model(
            &Params::default(),
            RateModelKind::WithActuators,
            RateInputs::Pwm,
        )
        .unwrap();
        let t = true;
        let f = false;
        // (C.1) with the servo position feedback a_{8,7} (see module docs).
        let want_a = vec![
            vec![f, f, f, f, t, t, f, f],
            vec![f, f, f, t, t, t, t, f],
            vec![f, f, f, t, t, t, t, f],
            vec![f, f, f, t, f, f, f, f],
            vec![f, f, f, f, t, f, f, f],
            vec![f, f, f, f, f, t, f, f],
            vec![f, f, f, f, f, f, f, t],
            vec![f, f, f, f, f, f, t, t],
        ];
        assert_eq!(pattern(&m.a), want_a);
        let want_b = vec![
            vec![f, f, f, f],
            vec![f, f, f, f],
            vec![f, f, f, f],
            vec![t, f, f, f],
            vec![f, t, f, f],
            vec![f, f, t, f],
            vec![f, f, f, f],
            vec![f, f, f, t],
        ];
        assert_eq!(pattern(&m.b), want_b);
        // The static model is the DC-gain reduction of the actuator model:
        // B_static = A_12 * (-A_22^-1 B_2) (the actuators have unit DC gain to their set point).
        let s = rate_model(&Params::default(), RateModelKind::Rates, RateInputs::Pwm).unwrap();
        let a12 = m.a.view((0, 3), (3, 5)).into_owned();
        let a22 = m.a.view((3, 3), (5, 5)).into_owned();
        let b2 = m.b.view((3, 0), (5, 4)).into_owned();
        let dc = -(a12 * a22.try_inverse().unwrap() * b2);
        assert!((dc - &s.b).amax() < 1e-9 * s.b.amax());
    }

    #[test]
    fn virtual_model_is_nearly_decoupled() {
        let m = rate_model(
            &Params::default(),
            RateModelKind::Rates,
            RateInputs::Virtual,
        )
        .unwrap();
        assert_eq!(m.b.ncols(), 3);
        // Diagonal dominance: each virtual input mainly drives its own axis
        // (pitch leaks into yaw through the tilted rear rotor: ~20 %).
        for i in 0..3 {
            for j in 0..3 {
                if i != j {
                    assert!(m.b[(i, j)].abs() < 0.25 * m.b[(i, i)].abs(), "{}", m.b);
                }
            }
            assert!(m.b[(i, i)] > 0.0, "{}", m.b);
        }
    }

    #[test]
    fn discretised_at_50_hz_matches_closed_form() {
        // A = 0 for the static model: Ad = I, Bd = ts * B exactly.
        let p = Params::default();
        let c = rate_model(&p, RateModelKind::Rates, RateInputs::Pwm).unwrap();
        let d = rate_model_discrete(&p, RateModelKind::Rates, RateInputs::Pwm, 0.02).unwrap();
        assert_eq!(d.ts, 0.02);
        assert!((&d.a - DMatrix::<f64>::identity(3, 3)).amax() < 1e-15);
        assert!((&d.b - &c.b * 0.02).amax() < 1e-15 * c.b.amax().max(1.0));
        let bad = rate_model_discrete(&p, RateModelKind::Rates, RateInputs::Pwm, -1.0);
        assert!(bad.is_err());
    }

    #[test]
    fn grey_box_vector_round_trip_and_errors() {
        let base = Params::default();
        let mut g = GreyBoxParams::from_params(&base);
        assert_eq!(g.apply(&base), base);
        assert_eq!(GreyBoxParams::from_array(&g.to_array()), g);
        for (i, name) in GreyBoxParams::NAMES.iter().enumerate() {
            assert_eq!(GreyBoxParams::index_of(name), Some(i));
            assert_eq!(g.get(i).unwrap(), g.to_array()[i]);
        }
        assert!(g.get(8).is_err());
        assert!(g.set(9, 1.0).is_err());
        // Doubling I_xx halves the roll row of B (b = dM/du / I_xx).
        let m1 = grey_box_rate_model(&g, &base, RateModelKind::Rates, RateInputs::Pwm).unwrap();
        g.set(0, 2.0 * base.ixx).unwrap();
        let m2 = grey_box_rate_model(&g, &base, RateModelKind::Rates, RateInputs::Pwm).unwrap();
        assert!((m2.b[(0, 1)] * 2.0 - m1.b[(0, 1)]).abs() < 1e-12);
        // Invalid values are errors, not panics.
        g.set(1, -1.0).unwrap();
        assert!(matches!(
            grey_box_rate_model(&g, &base, RateModelKind::Rates, RateInputs::Pwm),
            Err(ModelError::InvalidParam { name: "iyy", .. })
        ));
        g.set(1, f64::NAN).unwrap();
        assert!(grey_box_rate_model(&g, &base, RateModelKind::Rates, RateInputs::Pwm).is_err());
        // The thesis's initial guess cannot hover (no tilt cancels its
        // reaction torque): a clear error, not a panic.
        let e = grey_box_rate_model(
            &GreyBoxParams::thesis_initial_guess(),
            &base,
            RateModelKind::Rates,
            RateInputs::Pwm,
        )
        .unwrap_err();
        assert!(e.to_string().contains("trim"), "{e}");
    }
}
