//! The JSON interchange formats of `shared/FORMATS.md` (feature `std`),
//! the two small text inputs of the `kestrel` command: matrix files
//! ([`matrix_from_text`]) and parameter rows ([`parameter_rows`]), and the
//! number type and spelling of tables exported as Rust source
//! ([`ExportScalar`]).
//!
//! Readers reject an unknown `format`, a missing key, a wrong dimension or a
//! non-finite number with a [`FormatError`] that names the key and the
//! expected shape. The [`json`] module holds the checked getters and the
//! writer used by every format, so other crates' formats read and write the
//! same way.

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

mod export_scalar;
pub mod json;
mod matrix_file;
mod mpqp;
mod params;
mod ss;

pub use export_scalar::ExportScalar;
pub use matrix_file::matrix_from_text;
pub use mpqp::MpqpProblem;
pub use params::{NumberedRows, numbered_parameter_rows, parameter_rows};
pub use ss::SsModel;

/// What went wrong reading an interchange file.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The text is not JSON.
    #[error("invalid JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// The top level is not a JSON object.
    #[error("expected a JSON object at the top level")]
    NotAnObject,
    /// A required key is absent.
    #[error("missing key \"{key}\" (expected {expected})")]
    MissingKey {
        /// The key.
        key: String,
        /// What it should hold.
        expected: String,
    },
    /// The `format` key names another format.
    #[error("key \"format\": expected \"{expected}\", found {found}")]
    WrongFormat {
        /// The format this reader reads.
        expected: &'static str,
        /// What the file says (as JSON text).
        found: String,
    },
    /// A value has the wrong type or shape.
    #[error("key \"{key}\": expected {expected}, found {found}")]
    Shape {
        /// The key, with an index path where useful (`A[2]`).
        key: String,
        /// The expected shape, e.g. `a 4 x 4 matrix (array of 4 rows of 4 numbers)`.
        expected: String,
        /// What was there instead.
        found: String,
    },
    /// A number is NaN or infinite.
    #[error("key \"{key}\": expected a finite number, found {found}")]
    NonFinite {
        /// The key with the index path of the entry.
        key: String,
        /// The offending value as written.
        found: String,
    },
    /// A value has the right shape but violates a rule of the format.
    #[error("key \"{key}\": {reason}")]
    Invalid {
        /// The key.
        key: String,
        /// The rule that is broken.
        reason: String,
    },
    /// A line of a text table ([`parameter_rows`]) is wrong.
    #[error("line {line}{}: {reason}", .column.map_or_else(String::new, |c| format!(", column {c}")))]
    Line {
        /// The line, counted from 1 (blank lines included).
        line: usize,
        /// The column (field) counted from 1, when one field is wrong.
        column: Option<usize>,
        /// What is wrong.
        reason: String,
    },
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
}

impl FormatError {
    /// A [`FormatError::Invalid`] for `key`.
    pub fn invalid(key: impl Into<String>, reason: impl Into<String>) -> Self {
        FormatError::Invalid {
            key: key.into(),
            reason: reason.into(),
        }
    }
}

/// Reads a whole file, naming the path in the error.
pub fn read_text(path: &std::path::Path) -> Result<String, FormatError> {
    std::fs::read_to_string(path).map_err(|source| FormatError::Io {
        path: path.display().to_string(),
        source,
    })
}
