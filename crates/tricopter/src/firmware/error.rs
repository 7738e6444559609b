//! The firmware design's error type.

use crate::error::TricopterError;

/// One of the firmware's design files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignPart {
    /// The design model (`kestrel.ss.v1`).
    Model,
    /// The stationary Kalman filter (`kestrel.kalman.v1`).
    Kalman,
    /// The condensed MPC problem (`kestrel.mpqp.v1`).
    Problem,
}

impl std::fmt::Display for DesignPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            DesignPart::Model => "the design model",
            DesignPart::Kalman => "the Kalman filter",
            DesignPart::Problem => "the MPC problem",
        })
    }
}

/// Errors of the firmware design.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// A design file does not fit the firmware's loop.
    #[error("{what}: expected {expected}, found {found}")]
    Dimension {
        /// What was checked.
        what: &'static str,
        /// What the firmware needs.
        expected: String,
        /// What was given.
        found: String,
    },
    /// Two design files of the same sizes that were designed for different
    /// models (see [`estimator_model`](crate::firmware::estimator_model)).
    #[error("{first} and {second} do not belong together: {detail}")]
    Mismatch {
        /// The file found at fault.
        first: DesignPart,
        /// The file it was compared with.
        second: DesignPart,
        /// What differs.
        detail: String,
    },
    /// A design holds something the firmware's loop does not run.
    #[error("unsupported design: {0}")]
    Unsupported(String),
    /// A setting is outside its range.
    #[error("invalid setting {what}: {reason}")]
    InvalidSetting {
        /// The setting.
        what: &'static str,
        /// Why it is refused.
        reason: String,
    },
    /// kestrel-kalman refused the model.
    #[error("Kalman design: {0}")]
    Kalman(#[from] kestrel_kalman::KalmanError),
    /// The tricopter's problem or Kalman filter design refused the model.
    #[error("{0}")]
    Problem(#[from] TricopterError),
    /// kestrel-mpc refused the model.
    #[error("MPC problem: {0}")]
    Mpc(#[from] kestrel_mpc::MpcError),
    /// kestrel-fgm refused the problem.
    #[error("fast gradient: {0}")]
    Fgm(#[from] kestrel_fgm::FgmError),
    /// kestrel-empc refused the problem.
    #[error("explicit MPC: {0}")]
    Empc(#[from] kestrel_empc::EmpcError),
}

/// The 16-bit explicit table's errors as the design's (the same variants).
impl From<kestrel_avr_rt::explicit::quantize::QuantizeError> for DesignError {
    fn from(e: kestrel_avr_rt::explicit::quantize::QuantizeError) -> Self {
        use kestrel_avr_rt::explicit::quantize::QuantizeError;
        match e {
            QuantizeError::Dimension {
                what,
                expected,
                found,
            } => DesignError::Dimension {
                what,
                expected,
                found,
            },
            QuantizeError::Unsupported(what) => DesignError::Unsupported(what),
        }
    }
}

pub(super) fn dim(
    what: &'static str,
    expected: impl ToString,
    found: impl ToString,
) -> DesignError {
    DesignError::Dimension {
        what,
        expected: expected.to_string(),
        found: found.to_string(),
    }
}
