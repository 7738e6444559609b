//! Matrix files: one matrix in a JSON file, as a bare array of rows or
//! under a key of an object.

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

use super::FormatError;
use super::json;
use nalgebra::DMatrix;
use serde_json::Value;

/// Reads a matrix file: a JSON array of rows (`[[1, 0], [0, 2]]`), or an
/// object holding the matrix under `key` (`{"Q": [[1, 0], [0, 2]]}`, other
/// keys ignored), with optional fixed numbers of rows and columns (the
/// weights and covariances of `kestrel mpc` and `kestrel kalman`).
///
/// Errors name `key` and the index of a bad entry (`Q[0][1]`); a bare
/// `NaN` or `Infinity` (as Python writes them) is reported as a non-finite
/// entry, not as a syntax error. An empty array is a `0 x cols` matrix.
/// Memory follows the text, as with [`json::matrix_value`]: the expected
/// dimensions allocate nothing before the rows are read.
///
/// ```
/// use kestrel_core::formats::matrix_from_text;
/// let q = matrix_from_text("[[1, 0], [0, 2]]", "Q", Some(2), Some(2)).unwrap();
/// assert_eq!(q[(1, 1)], 2.0);
/// let g = matrix_from_text(r#"{"G": [[0], [1]], "note": "x"}"#, "G", Some(2), None).unwrap();
/// assert_eq!(g.shape(), (2, 1));
///
/// let err = matrix_from_text("[[1, NaN], [0, 1]]", "Q", None, None).unwrap_err();
/// assert!(err.to_string().contains("Q[0][1]"));
/// let err = matrix_from_text("[[1]]", "Q", Some(2), Some(2)).unwrap_err();
/// assert!(err.to_string().contains("a 2 x 2 matrix"));
/// ```
pub fn matrix_from_text(
    text: &str,
    key: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> Result<DMatrix<f64>, FormatError> {
    match json::parse_value(text)? {
        Value::Object(obj) => json::matrix(&obj, key, rows, cols),
        other @ Value::Array(_) => json::matrix_value(&other, key, rows, cols),
        other => Err(FormatError::Shape {
            key: key.into(),
            expected: format!("a matrix (an array of rows) or an object holding \"{key}\""),
            found: json::describe(&other),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str, rows: Option<usize>, cols: Option<usize>) -> String {
        matrix_from_text(text, "Q", rows, cols)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn bare_arrays_and_objects_read_the_same() {
        let bare = matrix_from_text("[[1, 2], [3, 4]]", "Q", None, Some(2)).unwrap();
        let obj =
            matrix_from_text(r#"{"R": 1, "Q": [[1, 2], [3, 4]]}"#, "Q", Some(2), None).unwrap();
        assert_eq!(bare, obj);
        assert_eq!(bare[(1, 0)], 3.0);
        let empty = matrix_from_text(" [] ", "Q", None, Some(3)).unwrap();
        assert_eq!(empty.shape(), (0, 3));
    }

    #[test]
    fn shapes_keys_and_entries_are_named() {
        assert!(err("[[1, 2, 3]]", Some(2), Some(2)).contains("found 1 rows"));
        assert!(err("[[1], [2, 3]]", None, None).contains("row 1 with 2 entries"));
        assert!(err(r#"{"R": [[1]]}"#, None, None).contains("missing key \"Q\""));
        assert!(err("[[1, Infinity]]", None, None).contains("Q[0][1]"));
        assert!(err("[[1, \"a\"]]", None, None).contains("Q[0][1]"));
        assert!(err("[[1, 1e999]]", None, None).contains("invalid JSON"));
        let scalar = err("2.5", None, None);
        assert!(
            scalar.contains("key \"Q\"") && scalar.contains("the number 2.5"),
            "{scalar}"
        );
        assert!(err("[[1]] x", None, None).starts_with("invalid JSON"));
    }

    #[test]
    fn a_bare_array_cannot_smuggle_another_key() {
        // The text is parsed as it is, not pasted into an object.
        assert!(err(r#"[[1]], "Q": [[2]]"#, None, None).starts_with("invalid JSON"));
    }

    #[test]
    fn a_short_text_cannot_claim_a_huge_matrix() {
        let e = err("[[], [], []]", None, Some(1 << 40));
        assert!(e.contains("row 0 with 0 entries"), "{e}");
        let e = err("[[1]]", Some(usize::MAX), Some(usize::MAX));
        assert!(e.contains("found 1 rows"), "{e}");
    }
}
