//! The design-time error type of the identification crate.

use std::string::String;

/// What went wrong in identification, validation or reduction.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SysidError {
    /// A data value is NaN or infinite.
    #[error("non-finite value in {what} at sample {sample} of experiment {experiment}")]
    NonFinite {
        /// The signal's name.
        what: String,
        /// The experiment index (0-based).
        experiment: usize,
        /// The sample index (0-based) within the experiment.
        sample: usize,
    },
    /// Signals of one experiment, or a model and data, disagree in size.
    #[error("dimension mismatch in {what}: expected {expected}, found {found}")]
    Dimension {
        /// Which quantity.
        what: String,
        /// The size needed.
        expected: usize,
        /// The size given.
        found: usize,
    },
    /// Not enough samples for the requested order and horizon.
    #[error("too few samples: {what} needs at least {needed}, the data have {found}")]
    TooFewSamples {
        /// What needs them.
        what: String,
        /// The number needed.
        needed: usize,
        /// The number available.
        found: usize,
    },
    /// An input does not vary, so it excites nothing.
    #[error(
        "input \"{name}\" is constant (standard deviation {std:e}); it cannot be identified from"
    )]
    ConstantInput {
        /// The input's name.
        name: String,
        /// Its standard deviation over the data set.
        std: f64,
    },
    /// An output does not vary.
    #[error("output \"{name}\" is constant; there is nothing to fit")]
    ConstantOutput {
        /// The output's name.
        name: String,
    },
    /// A setting or argument is outside its range; the text says which and why.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A CSV file could not be read or parsed.
    #[error("CSV {path}: {reason}")]
    Csv {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// A model is unstable where stability is required: its spectral
    /// radius is beyond `limit` (at least 1 for a Lyapunov equation, above
    /// `1 - stability_margin` for PEM's start model).
    #[error("{what} is unstable (spectral radius {radius:.6}, limit {limit})")]
    Unstable {
        /// Which matrix.
        what: String,
        /// Its spectral radius.
        radius: f64,
        /// The largest spectral radius allowed.
        limit: f64,
    },
    /// A size (model order, horizon) would need more memory or time than
    /// a documented limit allows ([`MAX_ORDER`](crate::MAX_ORDER),
    /// [`MAX_PEM_JACOBIAN_BYTES`](crate::MAX_PEM_JACOBIAN_BYTES), ...).
    #[error("{what} is too large: it would need {cost} ({limit})")]
    TooLarge {
        /// The method whose size it is.
        method: SizedMethod,
        /// The size asked for.
        what: String,
        /// What it would cost.
        cost: String,
        /// The limits.
        limit: String,
    },
    /// A linear-algebra step failed (singular matrix, no convergence).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// A run-time (kestrel-core) error.
    #[error(transparent)]
    Core(#[from] kestrel_core::Error),
}

/// The method a [`SysidError::TooLarge`] refusal is about, so that a caller
/// can say which of its settings goes on from it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SizedMethod {
    /// [`n4sid`](crate::n4sid()): the order and the block Hankel matrix.
    N4sid,
    /// [`pem`](crate::pem()): the Jacobian of one iteration (the prediction
    /// horizon and the parameters).
    Pem,
    /// [`arx`](crate::arx()) and the methods built on it (PBSID's VARX,
    /// ARMAX, the ARX reduction): the lags.
    Arx,
}

/// Shorthand for results of this crate.
pub type Result<T> = core::result::Result<T, SysidError>;

impl SysidError {
    pub(crate) fn invalid(s: impl Into<String>) -> Self {
        SysidError::InvalidArgument(s.into())
    }
    pub(crate) fn dim(what: impl Into<String>, expected: usize, found: usize) -> Self {
        SysidError::Dimension {
            what: what.into(),
            expected,
            found,
        }
    }
}
