//! The error type of the problems and the closed loop.

use kestrel_core::formats::FormatError;
use kestrel_mpc::MpcError;
use kestrel_sysid::SysidError;

/// What went wrong building a tricopter problem or flying the closed loop.
///
/// The messages of the first three variants read as kestrel-mpc's.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TricopterError {
    /// A model, vector or law has the wrong shape for the tricopter.
    #[error("{what}: expected {expected}, found {found}")]
    Dimension {
        /// The offending quantity (`"tricopter u0"`, `"control law"`, ...).
        what: String,
        /// The shape it must have.
        expected: String,
        /// The shape it has.
        found: String,
    },
    /// A vector holds NaN or an infinity.
    #[error("{0} contains NaN or an infinity")]
    NonFinite(String),
    /// A setting is outside its range, or a part of the loop (plant, gyro,
    /// Kalman filter) refused its configuration.
    #[error("invalid setting {what}: {reason}")]
    InvalidSetting {
        /// The setting or part.
        what: String,
        /// Why it is refused.
        reason: String,
    },
    /// kestrel-mpc refused the problem or its solver failed.
    #[error(transparent)]
    Mpc(#[from] MpcError),
    /// An interchange file is malformed.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// A run-time error of the shared core (a control law or the filter).
    #[error(transparent)]
    Core(#[from] kestrel_core::Error),
}

impl TricopterError {
    pub(crate) fn dim(
        what: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> Self {
        TricopterError::Dimension {
            what: what.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }
    pub(crate) fn setting(what: impl Into<String>, reason: impl Into<String>) -> Self {
        TricopterError::InvalidSetting {
            what: what.into(),
            reason: reason.into(),
        }
    }
}

/// kestrel-sysid's invalid-argument error.
pub(crate) fn sysid_invalid(reason: impl Into<String>) -> SysidError {
    SysidError::InvalidArgument(reason.into())
}

/// kestrel-sysid's dimension error.
pub(crate) fn sysid_dim(what: impl Into<String>, expected: usize, found: usize) -> SysidError {
    SysidError::Dimension {
        what: what.into(),
        expected,
        found,
    }
}
