//! Reading a file or bytes in whichever supported format they are.

use crate::error::{LogError, Result};
use crate::model::{Log, LogFormat, ReadOptions};
use crate::{betaflight, crazyflie, ulog};
use std::path::Path;

/// Reads every log in `bytes` (Betaflight files may hold several; the
/// other formats hold one), the format detected from the magic bytes.
pub fn read_bytes(bytes: &[u8], opts: &ReadOptions) -> Result<Vec<Log>> {
    match LogFormat::detect(bytes) {
        Some(LogFormat::Betaflight) => betaflight::read_all(bytes, opts),
        Some(LogFormat::Crazyflie) => Ok(vec![crazyflie::read(bytes, opts)?]),
        Some(LogFormat::Ulog) => Ok(vec![ulog::read(bytes, opts)?]),
        None => Err(LogError::UnknownFormat {
            found: bytes
                .iter()
                .take(8)
                .map(|b| format!("{b:02X}"))
                .collect::<Vec<_>>()
                .join(" "),
        }),
    }
}

/// Reads every log in the file at `path` ([`read_bytes`]).
pub fn read_file(path: &Path, opts: &ReadOptions) -> Result<Vec<Log>> {
    let bytes = std::fs::read(path).map_err(|source| LogError::Io {
        path: path.display().to_string(),
        source,
    })?;
    read_bytes(&bytes, opts)
}
