//! The number type of exported tables ([`ExportScalar`]).

use crate::error::EmpcError;
use kestrel_core::{Q16, Scalar};

/// The number type of exported tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportScalar {
    /// `f32` tables.
    F32,
    /// `kestrel_core::Q16` (Q15.16 saturating fixed point) tables.
    Q16,
    /// `f64` tables (host use, or a reference build of the firmware).
    F64,
}

impl ExportScalar {
    /// Bytes per number.
    pub fn bytes(self) -> usize {
        match self {
            ExportScalar::F32 | ExportScalar::Q16 => 4,
            ExportScalar::F64 => 8,
        }
    }

    /// The Rust type of the numbers.
    pub fn rust_type(self) -> &'static str {
        match self {
            ExportScalar::F32 => "f32",
            ExportScalar::Q16 => "kestrel_core::Q16",
            ExportScalar::F64 => "f64",
        }
    }

    /// One number as a Rust expression of [`ExportScalar::rust_type`];
    /// an error for a value `Q16` cannot hold.
    pub fn literal(self, v: f64) -> Result<String, EmpcError> {
        let float = |s: String| {
            if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
                s
            } else {
                format!("{s}.0")
            }
        };
        match self {
            ExportScalar::F32 => Ok(float(format!("{:?}", v as f32))),
            ExportScalar::F64 => Ok(float(format!("{v:?}"))),
            ExportScalar::Q16 => {
                if v.abs() >= 32767.0 {
                    return Err(EmpcError::InvalidArgument(format!(
                        "the value {v} does not fit Q16 (|x| < 32767); scale the problem or use f32"
                    )));
                }
                Ok(format!(
                    "kestrel_core::Q16::from_bits({})",
                    Q16::from_f64(v).to_bits()
                ))
            }
        }
    }
}
