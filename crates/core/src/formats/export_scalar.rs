//! The number type of generated Rust tables ([`ExportScalar`]).

use crate::{Error, Q16, Scalar};
use std::{format, string::String};

/// The number type of tables exported as Rust source: the type the
/// generated `static` items hold and how one number is spelled.
///
/// Every exporter of kestrel (kestrel-empc's explicit-law tables,
/// kestrel-fgm's fast-gradient tables) writes its numbers through
/// [`ExportScalar::literal`], so one value is spelled alike in every
/// generated file.
///
/// ```
/// use kestrel_core::formats::ExportScalar;
///
/// assert_eq!(ExportScalar::F32.literal(0.1).unwrap(), "0.1");
/// assert_eq!(ExportScalar::F64.literal(2.0).unwrap(), "2.0");
/// assert_eq!(
///     ExportScalar::Q16.literal(0.5).unwrap(),
///     "kestrel_core::Q16::from_bits(32768)"
/// );
/// assert!(ExportScalar::Q16.literal(40_000.0).is_err());
/// assert!(ExportScalar::F32.literal(f64::NAN).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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

    /// One number as a Rust expression of [`ExportScalar::rust_type`]:
    /// the shortest decimal that reads back to the same `f32` / `f64`
    /// (always with a `.` or an exponent, so it is a float literal), or
    /// `kestrel_core::Q16::from_bits(raw)` with `v` rounded to the nearest
    /// Q15.16 value.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN or an infinity (no literal spells
    /// them); [`Error::OutOfRange`] for a value the type cannot hold
    /// (beyond `f32::MAX`, or outside Q15.16's `[-32768, 32768)` after
    /// rounding), rather than a saturated or infinite table entry.
    pub fn literal(self, v: f64) -> Result<String, Error> {
        if !v.is_finite() {
            return Err(Error::NonFinite);
        }
        let float = |s: String| {
            if s.contains('.') || s.contains('e') {
                s
            } else {
                format!("{s}.0")
            }
        };
        match self {
            ExportScalar::F32 => {
                let x = v as f32;
                if !x.is_finite() {
                    return Err(Error::OutOfRange);
                }
                Ok(float(format!("{x:?}")))
            }
            ExportScalar::F64 => Ok(float(format!("{v:?}"))),
            ExportScalar::Q16 => {
                let raw = (v * 65_536.0).round();
                if raw < f64::from(i32::MIN) || raw > f64::from(i32::MAX) {
                    return Err(Error::OutOfRange);
                }
                Ok(format!(
                    "kestrel_core::Q16::from_bits({})",
                    Q16::from_f64(v).to_bits()
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literals_read_back_exactly() {
        for v in [0.0, -0.0, 1.0, -3.0, 0.1, 1e-30, 123_456.789, 1e30, -2.5e-7] {
            let s = ExportScalar::F64.literal(v).unwrap();
            assert!(s.contains('.') || s.contains('e'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{s}");
            let s = ExportScalar::F32.literal(v).unwrap();
            assert!(s.contains('.') || s.contains('e'), "{s}");
            assert_eq!(s.parse::<f32>().unwrap().to_bits(), (v as f32).to_bits());
        }
    }

    #[test]
    fn q16_literals_hold_the_rounded_value_and_refuse_beyond_the_range() {
        let bits = |s: String| -> i32 {
            s.strip_prefix("kestrel_core::Q16::from_bits(")
                .and_then(|r| r.strip_suffix(')'))
                .unwrap()
                .parse()
                .unwrap()
        };
        assert_eq!(bits(ExportScalar::Q16.literal(1.0).unwrap()), 65_536);
        assert_eq!(bits(ExportScalar::Q16.literal(-0.25).unwrap()), -16_384);
        // The range's ends: -32768 exactly, and the largest value below 32768.
        assert_eq!(
            bits(ExportScalar::Q16.literal(-32_768.0).unwrap()),
            i32::MIN
        );
        let top = f64::from(i32::MAX) / 65_536.0;
        assert_eq!(bits(ExportScalar::Q16.literal(top).unwrap()), i32::MAX);
        for v in [32_768.0, -32_768.0 - 1.0 / 65_536.0, 1e9] {
            assert_eq!(ExportScalar::Q16.literal(v), Err(Error::OutOfRange), "{v}");
        }
    }

    #[test]
    fn non_finite_and_overflowing_values_are_refused() {
        for s in [ExportScalar::F32, ExportScalar::F64, ExportScalar::Q16] {
            for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                assert_eq!(s.literal(v), Err(Error::NonFinite));
            }
        }
        assert_eq!(ExportScalar::F32.literal(1e39), Err(Error::OutOfRange));
        assert_eq!(ExportScalar::F32.literal(-1e39), Err(Error::OutOfRange));
        assert!(ExportScalar::F64.literal(1e300).is_ok());
    }
}
