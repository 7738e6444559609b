//! The firmware's dimensions and the settings of its design.

use crate::problems::ProblemSize;
use kestrel_fgm::Preconditioner;

/// Inputs of the tricopter (`pwm1, pwm2, pwm3, servo`).
pub const NU: usize = 4;
/// Measured outputs (`p, q, r`).
pub const NY: usize = 3;
/// Law parameters beyond the states: three rate references and the throttle.
pub const NR: usize = 4;
/// Servo centre pulse (us) the mixer adds to the servo trim.
pub const SERVO_CENTER: f64 = crate::constants::pwm::SERVO_CENTER;

/// How many fast-gradient iterations the firmware runs each period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IterationBudget {
    /// The certified cold-start count (every period meets the accuracy).
    Certified,
    /// A fixed count, warm-started from the previous period (not certified).
    WarmFixed(usize),
}

/// The state coordinates the firmware runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Realization {
    /// The model's own coordinates.
    AsGiven,
    /// Real Schur form `z = Q' x` (`Q` orthogonal): `A` becomes upper
    /// quasi-triangular, so the Kalman time update skips the zeros below
    /// it. Kalman filtering and the output-weighted MPC are invariant
    /// under the change of coordinates.
    Schur,
}

/// Settings of the firmware design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DesignSettings {
    /// Largest error (us) of any input of the fast-gradient solution
    /// against the exact optimum; sets the certificate's `eps`.
    pub max_input_error_us: f64,
    /// Preconditioner of the fast gradient method.
    pub preconditioner: Preconditioner,
    /// The MPC problem built when none is given ([`FirmwareDesign::from_model`](crate::firmware::FirmwareDesign::from_model)).
    pub size: ProblemSize,
    /// Iterations per period.
    pub budget: IterationBudget,
    /// Coordinates of the design model ([`FirmwareDesign::from_model`](crate::firmware::FirmwareDesign::from_model) only;
    /// [`FirmwareDesign::new`](crate::firmware::FirmwareDesign::new) keeps the given files' coordinates).
    pub realization: Realization,
}

impl Default for DesignSettings {
    /// 1 us, optimal diagonal preconditioning, the thesis-sized problem,
    /// the certified count, real Schur coordinates.
    fn default() -> Self {
        DesignSettings {
            max_input_error_us: 1.0,
            preconditioner: Preconditioner::OptimalDiagonal,
            size: ProblemSize::Thesis,
            budget: IterationBudget::Certified,
            realization: Realization::Schur,
        }
    }
}
