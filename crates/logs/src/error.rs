//! The crate's error type.

use crate::model::LogFormat;

/// Why a log could not be read, selected, resampled or written.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// Reading the file failed.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The first bytes match no supported format.
    #[error(
        "not a flight log kestrel reads: the first bytes {found} are neither a Betaflight blackbox header (\"H Product:Blackbox\"), a Crazyflie uSD log (0xBC) nor a PX4 ULog (\"ULog\" 0x01 0x12 0x35)"
    )]
    UnknownFormat {
        /// The first bytes, in hexadecimal.
        found: String,
    },
    /// The bytes at `offset` are not what the format requires there.
    #[error("{format} log, byte offset {offset}: expected {expected}, found {found}")]
    Corrupt {
        /// The format being read.
        format: LogFormat,
        /// Byte offset from the start of the file.
        offset: u64,
        /// What the format requires at that offset.
        expected: String,
        /// What the file holds there.
        found: String,
    },
    /// The file ends inside a record.
    #[error(
        "{format} log truncated at byte offset {offset}: expected {expected}, but the file ends at byte {len}"
    )]
    Truncated {
        /// The format being read.
        format: LogFormat,
        /// Byte offset of the incomplete record.
        offset: u64,
        /// What the record needs.
        expected: String,
        /// Length of the file.
        len: u64,
    },
    /// A signal asked for is not in the log (or not uniquely).
    #[error("signal \"{name}\": {reason}")]
    Signal {
        /// The name asked for.
        name: String,
        /// Why it cannot be used, with the names that can.
        reason: String,
    },
    /// A setting is out of its range.
    #[error("{0}")]
    Invalid(String),
    /// Nothing is left to write (no airborne segment, no samples).
    #[error("{0}")]
    Empty(String),
}

/// The crate's result type.
pub type Result<T> = std::result::Result<T, LogError>;
