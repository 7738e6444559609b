//! The error type of the problems and the closed loop.

use kestrel_core::formats::FormatError;
use kestrel_mpc::MpcError;
use kestrel_sysid::SysidError;

/// What went wrong building a tricopter problem or flying the closed loop.
///
/// A wrong shape, a NaN or a refused setting is reported in kestrel-mpc's
/// terms ([`MpcError::Dimension`], [`MpcError::NonFinite`],
/// [`MpcError::InvalidSetting`]) whether kestrel-mpc or this crate found
/// it, so each message is written once.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TricopterError {
    /// A model, vector, law or setting was refused (by kestrel-mpc, or by
    /// this crate: `"tricopter u0"`, `"control law"`, a part of the loop
    /// such as the plant, gyro or Kalman filter), or kestrel-mpc's solver
    /// failed.
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
    /// kestrel-mpc's [`MpcError::Dimension`].
    pub(crate) fn dim(
        what: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> Self {
        MpcError::dim(what, expected, found).into()
    }
    /// kestrel-mpc's [`MpcError::InvalidSetting`].
    pub(crate) fn setting(what: impl Into<String>, reason: impl Into<String>) -> Self {
        MpcError::setting(what, reason).into()
    }
    /// kestrel-mpc's [`MpcError::NonFinite`].
    pub(crate) fn non_finite(what: impl Into<String>) -> Self {
        MpcError::NonFinite(what.into()).into()
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
