//! Checked JSON getters and a matrix-friendly writer shared by all formats.
//!
//! ```
//! use kestrel_core::formats::json;
//! let obj = json::parse_object(r#"{"format": "x", "A": [[1, 2], [3, 4]]}"#).unwrap();
//! let a = json::matrix(&obj, "A", Some(2), Some(2)).unwrap();
//! assert_eq!(a[(1, 0)], 3.0);
//! let err = json::matrix(&obj, "A", Some(3), Some(2)).unwrap_err();
//! assert!(err.to_string().contains("\"A\""));
//! assert!(err.to_string().contains("3 x 2"));
//! ```

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

use super::FormatError;
use nalgebra::{DMatrix, DVector};
use serde_json::{Map, Value};

/// A parsed JSON object.
pub type Object = Map<String, Value>;

/// Parses text into a JSON object.
///
/// Bare `NaN`/`Infinity` tokens (as Python's `json.dump` writes them) are
/// not JSON; rather than a bare syntax error, they are read as strings so
/// that the getters can name the key holding the non-finite value.
pub fn parse_object(text: &str) -> Result<Object, FormatError> {
    match parse_value(text)? {
        Value::Object(m) => Ok(m),
        _ => Err(FormatError::NotAnObject),
    }
}

/// Parses text into a JSON value of any kind (an object, an array, ...),
/// reading bare `NaN`/`Infinity` tokens as strings as [`parse_object`] does.
pub fn parse_value(text: &str) -> Result<Value, FormatError> {
    match serde_json::from_str(text) {
        Ok(v) => Ok(v),
        Err(e) => {
            let quoted = quote_non_finite_tokens(text);
            match serde_json::from_str(&quoted) {
                Ok(v) if quoted != text => Ok(v),
                _ => Err(FormatError::Json(e)),
            }
        }
    }
}

/// Parses text into a JSON object keeping only the entries named in
/// `keys`: the values under other keys are checked as JSON but never
/// built, so a file whose bulk lies under a key the reader does not need
/// (a solution's region list) costs its text, not a tree of values several
/// times its size. Errors, and bare `NaN`/`Infinity` tokens, as in
/// [`parse_object`]; of a key given twice the last value is kept.
///
/// ```
/// use kestrel_core::formats::json;
/// let text = r#"{"format": "x", "p": 2, "regions": [[1, 2], [3, 4]]}"#;
/// let obj = json::parse_object_keys(text, &["format", "p"]).unwrap();
/// assert_eq!(obj.len(), 2);
/// assert!(obj.get("regions").is_none());
/// assert!(json::parse_object_keys(r#"{"p": 2, "regions": [1,"#, &["p"]).is_err());
/// ```
pub fn parse_object_keys(text: &str, keys: &[&str]) -> Result<Object, FormatError> {
    if !text.trim_start().starts_with('{') {
        // Not an object (or not JSON): the whole parser names what it is.
        return parse_object(text);
    }
    match keep_keys(text, keys) {
        Ok(m) => Ok(m),
        Err(e) => {
            let quoted = quote_non_finite_tokens(text);
            match keep_keys(&quoted, keys) {
                Ok(m) if quoted != text => Ok(m),
                _ => Err(FormatError::Json(e)),
            }
        }
    }
}

/// The object of `text` with the entries `keys` only (the whole text read).
fn keep_keys(text: &str, keys: &[&str]) -> Result<Object, serde_json::Error> {
    use serde::de::DeserializeSeed;
    let mut de = serde_json::Deserializer::from_str(text);
    let obj = KeepKeys(keys).deserialize(&mut de)?;
    de.end()?;
    Ok(obj)
}

/// A JSON object reader that builds the values of the named keys only.
struct KeepKeys<'k>(&'k [&'k str]);

impl<'de> serde::de::DeserializeSeed<'de> for KeepKeys<'_> {
    type Value = Object;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Object, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> serde::de::Visitor<'de> for KeepKeys<'_> {
    type Value = Object;
    fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("a JSON object")
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Object, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if self.0.contains(&key.as_str()) {
                let v = map.next_value::<Value>()?;
                out.insert(key, v);
            } else {
                map.next_value::<serde::de::IgnoredAny>()?;
            }
        }
        Ok(out)
    }
}

/// Replaces bare `NaN`, `Infinity` and `-Infinity` outside strings by quoted strings.
fn quote_non_finite_tokens(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 16);
    let mut in_str = false;
    let mut escaped = false;
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if in_str {
            out.push(c);
            if escaped {
                escaped = false;
            } else if c == '\\' {
                escaped = true;
            } else if c == '"' {
                in_str = false;
            }
            rest = &rest[c.len_utf8()..];
            continue;
        }
        let mut matched = false;
        for tok in ["-Infinity", "Infinity", "NaN"] {
            if rest.starts_with(tok) {
                out.push('"');
                out.push_str(tok);
                out.push('"');
                rest = &rest[tok.len()..];
                matched = true;
                break;
            }
        }
        if matched {
            continue;
        }
        if c == '"' {
            in_str = true;
        }
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    out
}

/// Checks the `format` key.
pub fn check_format(obj: &Object, expected: &'static str) -> Result<(), FormatError> {
    match obj.get("format") {
        None => Err(FormatError::MissingKey {
            key: "format".into(),
            expected: format!("\"{expected}\""),
        }),
        Some(Value::String(s)) if s == expected => Ok(()),
        Some(v) => Err(FormatError::WrongFormat {
            expected,
            found: v.to_string(),
        }),
    }
}

/// A short description of a value for error messages (`an array of 3 entries`).
pub(super) fn describe(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => format!("the boolean {b}"),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) => format!("the string {s:?}"),
        Value::Array(a) => format!("an array of {} entries", a.len()),
        Value::Object(_) => "an object".into(),
    }
}

/// Reads one finite number at `path` (used for error messages).
pub fn number_value(v: &Value, path: &str) -> Result<f64, FormatError> {
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(FormatError::NonFinite {
                key: path.into(),
                found: n.to_string(),
            }),
        },
        Value::String(s)
            if matches!(
                s.as_str(),
                "NaN" | "Infinity" | "-Infinity" | "nan" | "inf" | "-inf"
            ) =>
        {
            Err(FormatError::NonFinite {
                key: path.into(),
                found: s.clone(),
            })
        }
        other => Err(FormatError::Shape {
            key: path.into(),
            expected: "a finite number".into(),
            found: describe(other),
        }),
    }
}

fn required<'a>(obj: &'a Object, key: &str, expected: &str) -> Result<&'a Value, FormatError> {
    obj.get(key).ok_or_else(|| FormatError::MissingKey {
        key: key.into(),
        expected: expected.into(),
    })
}

fn dim(d: Option<usize>) -> String {
    d.map_or_else(|| "n".to_string(), |v| v.to_string())
}

fn matrix_shape(rows: Option<usize>, cols: Option<usize>) -> String {
    format!(
        "a {} x {} matrix (array of {} rows of {} numbers)",
        dim(rows),
        dim(cols),
        dim(rows),
        dim(cols)
    )
}

/// Reads a required number.
pub fn number(obj: &Object, key: &str) -> Result<f64, FormatError> {
    number_value(required(obj, key, "a finite number")?, key)
}

/// Reads an optional number.
pub fn opt_number(obj: &Object, key: &str) -> Result<Option<f64>, FormatError> {
    obj.get(key).map(|v| number_value(v, key)).transpose()
}

/// Reads a matrix value (row-major array of rows) with optional fixed sizes.
/// An empty array is a `0 x cols` matrix (cols taken from `cols`, else 0).
pub fn matrix_value(
    v: &Value,
    key: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> Result<DMatrix<f64>, FormatError> {
    let shape_err = |found: String| FormatError::Shape {
        key: key.into(),
        expected: matrix_shape(rows, cols),
        found,
    };
    let arr = v.as_array().ok_or_else(|| shape_err(describe(v)))?;
    if let Some(r) = rows
        && arr.len() != r
    {
        return Err(shape_err(format!("{} rows", arr.len())));
    }
    let ncols = match (arr.first(), cols) {
        (Some(Value::Array(first)), None) => first.len(),
        (_, Some(c)) => c,
        (None, None) => 0,
        (Some(other), None) => return Err(shape_err(format!("row 0 is {}", describe(other)))),
    };
    // Entries are collected as they are read (not rows x cols allocated
    // up front), so memory follows the text: a short file cannot claim a
    // huge matrix.
    let mut entries = Vec::new();
    for (i, row) in arr.iter().enumerate() {
        let row = row
            .as_array()
            .ok_or_else(|| shape_err(format!("row {i} is {}", describe(row))))?;
        if row.len() != ncols {
            return Err(shape_err(format!("row {i} with {} entries", row.len())));
        }
        for (j, x) in row.iter().enumerate() {
            entries.push(number_value(x, &format!("{key}[{i}][{j}]"))?);
        }
    }
    Ok(DMatrix::from_row_slice(arr.len(), ncols, &entries))
}

/// Reads a required matrix.
pub fn matrix(
    obj: &Object,
    key: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> Result<DMatrix<f64>, FormatError> {
    matrix_value(
        required(obj, key, &matrix_shape(rows, cols))?,
        key,
        rows,
        cols,
    )
}

/// Reads a required square matrix of any size.
pub fn square_matrix(obj: &Object, key: &str) -> Result<DMatrix<f64>, FormatError> {
    let m = matrix(obj, key, None, None)?;
    if m.ncols() != m.nrows() {
        return Err(FormatError::Shape {
            key: key.into(),
            expected: "a square matrix".into(),
            found: format!("a {} x {} matrix", m.nrows(), m.ncols()),
        });
    }
    Ok(m)
}

/// Reads an optional matrix.
pub fn opt_matrix(
    obj: &Object,
    key: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> Result<Option<DMatrix<f64>>, FormatError> {
    obj.get(key)
        .map(|v| matrix_value(v, key, rows, cols))
        .transpose()
}

/// Reads a vector value (plain array of numbers) with an optional fixed length.
pub fn vector_value(v: &Value, key: &str, len: Option<usize>) -> Result<DVector<f64>, FormatError> {
    let expected = format!("a vector of {} numbers", dim(len));
    let arr = v.as_array().ok_or_else(|| FormatError::Shape {
        key: key.into(),
        expected: expected.clone(),
        found: describe(v),
    })?;
    if let Some(n) = len
        && arr.len() != n
    {
        return Err(FormatError::Shape {
            key: key.into(),
            expected,
            found: format!("{} entries", arr.len()),
        });
    }
    let mut out = DVector::zeros(arr.len());
    for (i, x) in arr.iter().enumerate() {
        out[i] = number_value(x, &format!("{key}[{i}]"))?;
    }
    Ok(out)
}

/// Reads a required vector.
pub fn vector(obj: &Object, key: &str, len: Option<usize>) -> Result<DVector<f64>, FormatError> {
    let expected = format!("a vector of {} numbers", dim(len));
    vector_value(required(obj, key, &expected)?, key, len)
}

/// Reads an optional vector.
pub fn opt_vector(
    obj: &Object,
    key: &str,
    len: Option<usize>,
) -> Result<Option<DVector<f64>>, FormatError> {
    obj.get(key).map(|v| vector_value(v, key, len)).transpose()
}

/// Reads an optional array of strings with an optional fixed length.
pub fn opt_strings(
    obj: &Object,
    key: &str,
    len: Option<usize>,
) -> Result<Option<Vec<String>>, FormatError> {
    let Some(v) = obj.get(key) else {
        return Ok(None);
    };
    let expected = format!("an array of {} strings", dim(len));
    let err = |found: String| FormatError::Shape {
        key: key.into(),
        expected: expected.clone(),
        found,
    };
    let arr = v.as_array().ok_or_else(|| err(describe(v)))?;
    if let Some(n) = len
        && arr.len() != n
    {
        return Err(err(format!("{} entries", arr.len())));
    }
    arr.iter()
        .map(|s| {
            s.as_str()
                .map(str::to_owned)
                .ok_or_else(|| err(describe(s)))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// A JSON value for a matrix (array of rows).
pub fn matrix_to_value(m: &DMatrix<f64>) -> Value {
    Value::Array(
        m.row_iter()
            .map(|r| Value::Array(r.iter().map(|&x| Value::from(x)).collect()))
            .collect(),
    )
}

/// A JSON value for a vector.
pub fn vector_to_value(v: &DVector<f64>) -> Value {
    Value::Array(v.iter().map(|&x| Value::from(x)).collect())
}

/// Writes an object as readable JSON: one key per line, and arrays of
/// numbers (vectors, matrix rows) each on one line.
pub fn to_pretty_string(obj: &Object) -> String {
    let mut out = String::new();
    write_value(&Value::Object(obj.clone()), 0, &mut out);
    out.push('\n');
    out
}

fn is_flat(v: &Value) -> bool {
    match v {
        Value::Array(a) => a.iter().all(|x| !x.is_array() && !x.is_object()),
        Value::Object(_) => false,
        _ => true,
    }
}

fn write_value(v: &Value, indent: usize, out: &mut String) {
    let pad = |n: usize| "  ".repeat(n);
    match v {
        Value::Object(m) if !m.is_empty() => {
            out.push_str("{\n");
            for (i, (k, val)) in m.iter().enumerate() {
                out.push_str(&pad(indent + 1));
                out.push_str(&Value::String(k.clone()).to_string());
                out.push_str(": ");
                write_value(val, indent + 1, out);
                if i + 1 < m.len() {
                    out.push(',');
                }
                out.push('\n');
            }
            out.push_str(&pad(indent));
            out.push('}');
        }
        Value::Array(a) if !is_flat(v) => {
            out.push_str("[\n");
            for (i, val) in a.iter().enumerate() {
                out.push_str(&pad(indent + 1));
                write_value(val, indent + 1, out);
                if i + 1 < a.len() {
                    out.push(',');
                }
                out.push('\n');
            }
            out.push_str(&pad(indent));
            out.push(']');
        }
        Value::Array(a) => {
            let items: Vec<String> = a.iter().map(Value::to_string).collect();
            out.push('[');
            out.push_str(&items.join(", "));
            out.push(']');
        }
        other => out.push_str(&other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` empty rows: `[[], [], ...]`.
    fn empty_rows(n: usize) -> String {
        format!("[{}]", vec!["[]"; n].join(","))
    }

    /// Found with the fuzz targets' size check: a matrix with a known column count
    /// was allocated (rows x cols) before its rows were checked, so 100,000
    /// empty rows where 100,000 columns were expected (600 kB of text)
    /// asked for an 80 GB matrix and aborted the process.
    #[test]
    fn a_matrix_is_not_allocated_before_its_rows_are_read() {
        let n = 100_000;
        let obj = parse_object(&format!(r#"{{"E": {}}}"#, empty_rows(n))).unwrap();
        let e = matrix(&obj, "E", Some(n), Some(n)).unwrap_err().to_string();
        assert!(
            e.contains("\"E\"") && e.contains("row 0 with 0 entries"),
            "{e}"
        );
        let e = matrix(&obj, "E", None, Some(n)).unwrap_err().to_string();
        assert!(e.contains("row 0 with 0 entries"), "{e}");
        let m = matrix(&obj, "E", None, Some(0)).unwrap();
        assert_eq!(m.shape(), (n, 0));
    }

    #[test]
    fn nan_literal_is_reported_with_its_key() {
        let obj = parse_object(r#"{"A": [[1, NaN]], "s": "NaN, Infinity"}"#).unwrap();
        let e = matrix(&obj, "A", None, None).unwrap_err();
        assert_eq!(
            e.to_string(),
            "key \"A[0][1]\": expected a finite number, found NaN"
        );
        // Strings are left alone.
        assert_eq!(obj["s"], Value::String("NaN, Infinity".into()));
    }

    #[test]
    fn shape_errors_name_key_and_shape() {
        let obj = parse_object(r#"{"B": [[1], [2, 3]], "v": [1, 2], "x": "a"}"#).unwrap();
        let e = matrix(&obj, "B", None, None).unwrap_err().to_string();
        assert!(
            e.contains("\"B\"") && e.contains("row 1 with 2 entries"),
            "{e}"
        );
        let e = vector(&obj, "v", Some(3)).unwrap_err().to_string();
        assert!(
            e.contains("a vector of 3 numbers") && e.contains("2 entries"),
            "{e}"
        );
        let e = matrix(&obj, "C", Some(2), Some(2)).unwrap_err().to_string();
        assert_eq!(
            e,
            "missing key \"C\" (expected a 2 x 2 matrix (array of 2 rows of 2 numbers))"
        );
        let e = square_matrix(&obj, "B").unwrap_err().to_string();
        assert!(e.contains("row 1 with 2 entries"), "{e}");
        let sq = parse_object(r#"{"S": [[1, 2]]}"#).unwrap();
        let e = square_matrix(&sq, "S").unwrap_err().to_string();
        assert_eq!(
            e,
            "key \"S\": expected a square matrix, found a 1 x 2 matrix"
        );
        let e = number(&obj, "x").unwrap_err().to_string();
        assert!(e.contains("the string \"a\""), "{e}");
        assert!(matches!(parse_object("[1]"), Err(FormatError::NotAnObject)));
        assert!(matches!(parse_object("{"), Err(FormatError::Json(_))));
    }

    #[test]
    fn huge_numbers_are_non_finite_errors() {
        let r = parse_object(r#"{"a": 1e999}"#);
        // serde_json refuses numbers out of range at parse time: an error either way.
        match r {
            Err(FormatError::Json(_)) => {}
            Ok(obj) => assert!(number(&obj, "a").is_err()),
            Err(e) => panic!("unexpected {e}"),
        }
    }

    #[test]
    fn pretty_writer_round_trips() {
        let mut obj = Object::new();
        obj.insert("format".into(), "t".into());
        obj.insert(
            "A".into(),
            matrix_to_value(&DMatrix::from_row_slice(2, 2, &[1.0, 0.1, -3e-20, 4.0])),
        );
        obj.insert("v".into(), vector_to_value(&DVector::from_vec(vec![])));
        let text = to_pretty_string(&obj);
        assert!(text.contains("[1.0, 0.1]"), "{text}");
        let back = parse_object(&text).unwrap();
        assert_eq!(back, obj);
    }

    /// The whole parse with the other keys removed afterwards.
    fn filtered(text: &str, keys: &[&str]) -> Result<Object, FormatError> {
        let mut obj = parse_object(text)?;
        obj.retain(|k, _| keys.contains(&k.as_str()));
        Ok(obj)
    }

    #[test]
    fn keys_only_parse_equals_the_filtered_whole_parse() {
        let keys = ["format", "p", "tables"];
        for text in [
            r#"{"format": "f", "p": 3, "region_list": [{"a": [[1, 2]], "b": [NaN]}], "tables": {"x": [1.5, -2]}}"#,
            r#"{"p": 1, "p": 2, "other": "a \"quoted\" NaN"}"#,
            r#"{"tables": {"v": [Infinity, -Infinity]}, "skip": {"deep": [[[[]]]]}}"#,
            r#"  {}  "#,
        ] {
            let got = parse_object_keys(text, &keys).unwrap();
            assert_eq!(got, filtered(text, &keys).unwrap(), "{text}");
            assert_eq!(
                serde_json::to_string(&got).unwrap(),
                serde_json::to_string(&filtered(text, &keys).unwrap()).unwrap(),
                "key order: {text}"
            );
        }
        // Errors in a skipped value, after the object, and what is not an object.
        for text in [
            r#"{"p": 1, "skip": [1, 2"#,
            r#"{"p": 1, "skip": [1, 2,]}"#,
            r#"{"p": 1} trailing"#,
            r#"{"p": 1, "skip": tru}"#,
        ] {
            assert!(
                matches!(parse_object_keys(text, &keys), Err(FormatError::Json(_))),
                "{text}"
            );
            assert!(parse_object(text).is_err(), "{text}");
        }
        assert!(matches!(
            parse_object_keys("[1]", &keys),
            Err(FormatError::NotAnObject)
        ));
    }

    /// JSON values of a few levels, numbers as the files hold them.
    fn json_value() -> impl proptest::strategy::Strategy<Value = Value> {
        use proptest::prelude::*;
        let leaf = prop_oneof![
            Just(Value::Null),
            any::<bool>().prop_map(Value::from),
            (-1e6f64..1e6).prop_map(Value::from),
            "[a-z ]{0,6}".prop_map(Value::from),
        ];
        leaf.prop_recursive(3, 24, 4, |inner| {
            prop_oneof![
                proptest::collection::vec(inner.clone(), 0..4).prop_map(Value::from),
                proptest::collection::vec(("[a-c]", inner), 0..4)
                    .prop_map(|kv| Value::Object(kv.into_iter().collect())),
            ]
        })
    }

    proptest::proptest! {
        /// For every object the keys-only parse keeps exactly the kept keys'
        /// values of the whole parse, compact or pretty.
        #[test]
        fn keys_only_parse_law(
            entries in proptest::collection::vec(("[a-e]", json_value()), 0..6),
            pretty in proptest::bool::ANY,
        ) {
            let obj: Object = entries.into_iter().collect();
            let text = if pretty {
                serde_json::to_string_pretty(&obj).unwrap()
            } else {
                serde_json::to_string(&obj).unwrap()
            };
            let keys = ["a", "c"];
            proptest::prop_assert_eq!(parse_object_keys(&text, &keys).unwrap(), filtered(&text, &keys).unwrap());
        }
    }
}
