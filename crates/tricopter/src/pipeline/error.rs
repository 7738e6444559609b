//! The pipeline's error: which stage failed, what it was doing, and the
//! library error underneath.

/// The error of [`crate::pipeline::run`].
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// A configuration value the pipeline cannot use.
    #[error("{message}")]
    Config {
        /// The TOML key, e.g. `mpc.larger` (the first the message names).
        key: String,
        /// The message, naming the key and the value.
        message: String,
    },
    /// Flight data the pipeline cannot use (too short, missing a flight).
    #[error("{0}")]
    Data(String),
    /// A library call failed; `context` says what the stage was doing.
    #[error("{context}: {source}")]
    Step {
        /// What the stage was doing.
        context: String,
        /// The library's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
}

impl PipelineError {
    /// A configuration error; the message starts with the key
    /// (`mpc.larger: ...`, `kalman.flight = 7: ...`).
    pub fn config_message(message: String) -> Self {
        let key = message
            .split([' ', ':', '[', '='])
            .next()
            .unwrap_or_default()
            .to_string();
        PipelineError::Config { key, message }
    }
}

/// `Result` of the pipeline.
pub type Result<T> = std::result::Result<T, PipelineError>;

/// Attaches what a stage was doing to a library error.
pub trait Context<T> {
    /// Wraps the error as [`PipelineError::Step`] with `context`.
    fn ctx(self, context: impl FnOnce() -> String) -> Result<T>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for std::result::Result<T, E> {
    fn ctx(self, context: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|e| PipelineError::Step {
            context: context(),
            source: Box::new(e),
        })
    }
}
