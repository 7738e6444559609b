//! The number type of exported tables: kestrel-core's [`ExportScalar`],
//! with its refusals as [`EmpcError`]s that name the value.

use crate::error::EmpcError;
pub use kestrel_core::formats::ExportScalar;

/// `scalar.literal(v)`, a value the type cannot hold refused with the value
/// and the type named (and, for a value beyond Q15.16's range, how to go
/// on).
pub(crate) fn literal(scalar: ExportScalar, v: f64) -> Result<String, EmpcError> {
    scalar.literal(v).map_err(|e| {
        let hint = if (scalar, e) == (ExportScalar::Q16, kestrel_core::Error::OutOfRange) {
            "; scale the problem or use f32"
        } else {
            ""
        };
        EmpcError::InvalidArgument(format!(
            "the table value {v} cannot be written as {}: {e}{hint}",
            scalar.rust_type()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_the_value_and_the_type() {
        assert_eq!(
            literal(ExportScalar::Q16, 1.5).unwrap(),
            "kestrel_core::Q16::from_bits(98304)"
        );
        let e = literal(ExportScalar::Q16, 40_000.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("40000") && e.contains("kestrel_core::Q16") && e.contains("use f32"),
            "{e}"
        );
        let e = literal(ExportScalar::F32, f64::INFINITY)
            .unwrap_err()
            .to_string();
        assert!(e.contains("inf") && e.contains("f32"), "{e}");
        // No advice to use f32 for a value no type can spell.
        assert!(!e.contains("use f32"), "{e}");
    }
}
