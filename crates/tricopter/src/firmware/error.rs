//! The firmware design's error type.

use crate::error::TricopterError;

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
