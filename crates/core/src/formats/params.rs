//! Parameter rows: a CSV text of parameter vectors (thetas), one per line.

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

use super::FormatError;

/// Reads parameter rows: one parameter vector of `p` numbers per line,
/// separated by commas (`kestrel fgm solve --thetas`, `kestrel empc eval
/// --thetas`).
///
/// - Blank lines are skipped; there is no header line.
/// - Lines end in `\n`, `\r\n` or `\r`; a leading UTF-8 byte order mark
///   is skipped.
/// - A field is trimmed; a number may be quoted (`"0.5"`).
/// - Every number must be finite (`nan`, `inf` and `1e999` are refused).
///
/// An error is a [`FormatError::Line`] naming the line (counted with the
/// blank ones) and, for a bad number, the column; a line with a wrong
/// count of numbers also names its row (the parameter's index, counted
/// from 1 without the blank lines). Memory follows the text: nothing is
/// allocated for `p` before a line is read.
///
/// ```
/// use kestrel_core::formats::parameter_rows;
/// let rows = parameter_rows("0.5, -1\n\n2,3\n", 2).unwrap();
/// assert_eq!(rows, [[0.5, -1.0], [2.0, 3.0]]);
///
/// let err = parameter_rows("1,2\n1,x\n", 2).unwrap_err().to_string();
/// assert_eq!(err, "line 2, column 2: expected a finite number, found \"x\"");
/// let err = parameter_rows("1,2\n\n1\n", 2).unwrap_err().to_string();
/// assert_eq!(err, "line 3: row 2 has 1 values, expected 2 numbers (one per parameter)");
/// ```
pub fn parameter_rows(text: &str, p: usize) -> Result<Vec<Vec<f64>>, FormatError> {
    numbered_parameter_rows(text, p).map(|r| r.rows)
}

/// Parameter rows with the line each was read from, so that a command can
/// name a row's line in the file when the file has blank lines.
#[derive(Clone, Debug, PartialEq)]
pub struct NumberedRows {
    /// The rows, `p` numbers each (as [`parameter_rows`] returns them).
    pub rows: Vec<Vec<f64>>,
    /// `lines[k]`: the line of `rows[k]`, counted from 1 with the blank ones.
    pub lines: Vec<usize>,
}

/// [`parameter_rows`] with each row's line ([`NumberedRows`]); the same
/// rules and errors.
///
/// ```
/// use kestrel_core::formats::numbered_parameter_rows;
/// let r = numbered_parameter_rows("\n0.5, -1\n\n2,3\n", 2).unwrap();
/// assert_eq!(r.rows, [[0.5, -1.0], [2.0, 3.0]]);
/// assert_eq!(r.lines, [2, 4]);
/// ```
pub fn numbered_parameter_rows(text: &str, p: usize) -> Result<NumberedRows, FormatError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut rows = Vec::new();
    let mut numbers = Vec::new();
    let lines = text
        .split('\n')
        .flat_map(|l| l.strip_suffix('\r').unwrap_or(l).split('\r'));
    for (k, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let row = line
            .split(',')
            .enumerate()
            .map(|(j, field)| {
                number(field).ok_or_else(|| FormatError::Line {
                    line: k + 1,
                    column: Some(j + 1),
                    reason: format!("expected a finite number, found {:?}", field.trim()),
                })
            })
            .collect::<Result<Vec<f64>, _>>()?;
        if row.len() != p {
            return Err(FormatError::Line {
                line: k + 1,
                column: None,
                reason: format!(
                    "row {} has {} values, expected {p} numbers (one per parameter)",
                    rows.len() + 1,
                    row.len()
                ),
            });
        }
        rows.push(row);
        numbers.push(k + 1);
    }
    Ok(NumberedRows {
        rows,
        lines: numbers,
    })
}

/// A trimmed field, possibly quoted, as a finite number.
fn number(field: &str) -> Option<f64> {
    let field = field.trim();
    let field = field
        .strip_prefix('"')
        .and_then(|f| f.strip_suffix('"'))
        .map_or(field, str::trim);
    field.parse::<f64>().ok().filter(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str, p: usize) -> String {
        parameter_rows(text, p).unwrap_err().to_string()
    }

    #[test]
    fn rows_are_read_with_blank_lines_spaces_and_quotes() {
        let text = "\u{feff}0.5, 0.25\r\n  \r\n-2,\"0\"\r\n\n2e0 ,\" 0.5 \"";
        assert_eq!(
            parameter_rows(text, 2).unwrap(),
            [[0.5, 0.25], [-2.0, 0.0], [2.0, 0.5]]
        );
        // Old Mac line ends.
        assert_eq!(parameter_rows("1\r2\r", 1).unwrap(), [[1.0], [2.0]]);
        // Each row's line counts the blank ones (and each line end style).
        assert_eq!(numbered_parameter_rows(text, 2).unwrap().lines, [1, 3, 5]);
        assert_eq!(
            numbered_parameter_rows("\r1\r\r2", 1).unwrap().lines,
            [2, 4]
        );
    }

    #[test]
    fn an_empty_text_has_no_rows() {
        assert!(parameter_rows("", 3).unwrap().is_empty());
        assert!(parameter_rows("\n \n\t\n", 0).unwrap().is_empty());
    }

    #[test]
    fn non_numbers_and_non_finite_numbers_name_line_and_column() {
        assert_eq!(
            err("1,2\n\n1,x\n", 2),
            "line 3, column 2: expected a finite number, found \"x\""
        );
        for bad in ["nan", "inf", "-inf", "1e999", "NaN", "infinity", ""] {
            let e = err(&format!("1,{bad}\n"), 2);
            assert!(
                e.starts_with("line 1, column 2: expected a finite number"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn a_header_line_is_refused() {
        assert_eq!(
            err("theta1,theta2\n1,2\n", 2),
            "line 1, column 1: expected a finite number, found \"theta1\""
        );
    }

    #[test]
    fn a_wrong_count_names_line_and_row() {
        assert_eq!(
            err("1\n", 2),
            "line 1: row 1 has 1 values, expected 2 numbers (one per parameter)"
        );
        assert_eq!(
            err("1,2\n\n1,2,3\n", 2),
            "line 3: row 2 has 3 values, expected 2 numbers (one per parameter)"
        );
        assert!(err("1\n", 0).contains("expected 0"));
    }

    #[test]
    fn a_huge_p_allocates_nothing_up_front() {
        assert_eq!(
            err("1,2\n", usize::MAX),
            format!(
                "line 1: row 1 has 2 values, expected {} numbers (one per parameter)",
                usize::MAX
            )
        );
    }
}
