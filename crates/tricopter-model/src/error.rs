//! The design-time error type of the crate.

/// What can go wrong building or running the tricopter model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A physical parameter is out of its range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParam {
        /// The parameter's field name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The rule it breaks.
        reason: &'static str,
    },
    /// An input or state contained NaN or an infinity.
    #[error("non-finite {what} (NaN or infinity)")]
    NonFinite {
        /// Which quantity (`"input"`, `"state"`, ...).
        what: &'static str,
    },
    /// A setting of a simulation or computation is out of its range.
    #[error("invalid setting {name}: {reason}")]
    InvalidSetting {
        /// The setting.
        name: &'static str,
        /// The rule it breaks.
        reason: String,
    },
    /// A simulation would need more memory or time than a documented
    /// limit allows ([`MAX_SIM_SECONDS`](crate::MAX_SIM_SECONDS),
    /// [`MAX_SIM_STEPS`](crate::MAX_SIM_STEPS)).
    #[error("{what} is too long: it would need {cost} ({limit})")]
    TooLarge {
        /// The size asked for.
        what: String,
        /// What it would cost.
        cost: String,
        /// The limit.
        limit: String,
    },
    /// The trim iteration did not reach its tolerance.
    #[error("trim did not converge: residual {residual:e} after {iterations} iterations")]
    TrimNotConverged {
        /// The final residual norm.
        residual: f64,
        /// Newton iterations taken.
        iterations: usize,
    },
    /// An error from kestrel-core (discretisation, formats).
    #[error("kestrel-core: {0}")]
    Core(#[from] kestrel_core::Error),
    /// An interchange-format error (building an `SsModel`).
    #[error(transparent)]
    Format(#[from] kestrel_core::formats::FormatError),
    /// Writing a log failed.
    #[error("writing CSV log: {0}")]
    Csv(String),
}
