//! What to estimate and how: the focus, the search settings, the spec.

use crate::error::sysid_invalid;
use kestrel_sysid::Result;
use kestrel_tricopter_model::{GreyBoxParams, Params, RateInputs, RateModelKind};

/// What the grey-box criterion measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GreyBoxFocus {
    /// Simulation errors, `K = 0` (output-error model).
    #[default]
    Simulation,
    /// One-step prediction errors; `K` estimated with the parameters.
    Prediction,
    /// Simulation errors for the physical parameters, then one-step
    /// errors for `K` alone with the physics fixed.
    SimulationThenNoise,
}

/// Settings of the Levenberg-Marquardt search of [`estimate_grey_box`](crate::ident::greybox::estimate_grey_box).
#[derive(Clone, Debug, PartialEq)]
pub struct GreyBoxSettings {
    /// Largest number of iterations (per stage).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Stop when `max |dJ/dθ| / J` is below this.
    pub gradient_tolerance: f64,
    /// Stop when the step is shorter than this relative to `1 + |θ|`.
    pub step_tolerance: f64,
    /// Central-difference step of the parametrisation derivative, in log scale.
    pub derivative_step: f64,
    /// Run the equation-error stage first (see [`Stage::EquationError`](crate::ident::greybox::Stage::EquationError)):
    /// robust against starts far from the truth, such as Table 7.1.
    pub equation_error_start: bool,
    /// Horizons of the k-step rows of the fit table.
    pub horizons: Vec<usize>,
}

impl Default for GreyBoxSettings {
    fn default() -> Self {
        GreyBoxSettings {
            max_iterations: 60,
            cost_tolerance: 1e-10,
            gradient_tolerance: 1e-10,
            step_tolerance: 1e-10,
            derivative_step: 1e-5,
            equation_error_start: true,
            horizons: vec![1, 5],
        }
    }
}

/// What to estimate and how.
#[derive(Clone, Debug, PartialEq)]
pub struct GreyBoxSpec {
    /// Which parameters are free, in [`GreyBoxParams::NAMES`] order; the
    /// others stay at the initial value.
    pub free: [bool; 8],
    /// The rate model's states.
    pub kind: RateModelKind,
    /// The rate model's inputs (the data must have the same columns).
    pub inputs: RateInputs,
    /// The criterion.
    pub focus: GreyBoxFocus,
    /// Add `ny` integrating disturbance states (angular accelerations on
    /// the measured rates, `d' = 0`, `p' = ... + d_p`): a noise model for
    /// unmeasured torques (gusts, trim offsets) driven through `K`.
    pub disturbance: bool,
    /// The known parameters (mass, arm length, ESC map, servo gain, spins);
    /// its grey-box fields are replaced by the estimate.
    pub base: Params,
    /// Lower bounds (exclusive of zero: every parameter stays positive).
    pub lower: GreyBoxParams,
    /// Upper bounds.
    pub upper: GreyBoxParams,
    /// The measured operating point `[pwm1, pwm2, pwm3, servo]` (us, e.g.
    /// the means removed from the data): when given, `k_t` and `k_tau` are
    /// computed from it by [`thrust_and_drag_from_trim`](crate::ident::greybox::thrust_and_drag_from_trim) and held fixed
    /// (the rate data alone determine them poorly, see the module docs).
    pub operating_point: Option<[f64; 4]>,
    /// Search settings.
    pub settings: GreyBoxSettings,
}

impl Default for GreyBoxSpec {
    /// All eight parameters free, the model with actuators and PWM inputs,
    /// simulation focus, the default aircraft's known parameters, no bounds
    /// but positivity.
    fn default() -> Self {
        GreyBoxSpec {
            free: [true; 8],
            kind: RateModelKind::WithActuators,
            inputs: RateInputs::Pwm,
            focus: GreyBoxFocus::Simulation,
            disturbance: false,
            base: Params::default(),
            lower: GreyBoxParams::from_array(&[0.0; 8]),
            upper: GreyBoxParams::from_array(&[f64::INFINITY; 8]),
            operating_point: None,
            settings: GreyBoxSettings::default(),
        }
    }
}

impl GreyBoxSpec {
    /// The spec for closed-loop flights with gusts (the simulator's
    /// flights no. 2 and 3): [`GreyBoxFocus::Prediction`] with the
    /// integrating disturbance states, all parameters free. The
    /// simulation focus is biased there: the gust torque is unmeasured and
    /// the pilot's inputs react to it, so the output-error model of the
    /// integrating rates trades physics for drift.
    pub fn closed_loop_flights(base: Params) -> Self {
        GreyBoxSpec {
            focus: GreyBoxFocus::Prediction,
            disturbance: true,
            base,
            ..Default::default()
        }
    }

    /// The default spec with only the named parameters free (names of
    /// [`GreyBoxParams::NAMES`]); an unknown name is an error.
    pub fn with_free(names: &[&str]) -> Result<Self> {
        let mut free = [false; 8];
        for n in names {
            let i = GreyBoxParams::index_of(n).ok_or_else(|| {
                sysid_invalid(format!(
                    "unknown grey-box parameter \"{n}\" (expected one of {:?})",
                    GreyBoxParams::NAMES
                ))
            })?;
            free[i] = true;
        }
        Ok(GreyBoxSpec {
            free,
            ..Default::default()
        })
    }
}
