//! `kestrel.ss.v1`: a discrete (or, with `ts` 0, continuous) state-space model.

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

use super::FormatError;
use super::json::{self, Object};
use crate::error::Error;
use crate::linalg;
use crate::model::DiscreteLinearModel;
use nalgebra::{DMatrix, DVector};
use serde_json::Value;

/// A state-space model as stored in `kestrel.ss.v1` files.
///
/// `x+ = A x + B (u - u0) + K e`, `y - y0 = C x + D (u - u0) + e`. With
/// `ts == 0` the model is continuous time (`x' = A x + B u`).
///
/// ```
/// use kestrel_core::formats::SsModel;
/// let m = SsModel::from_json_str(r#"{"format": "kestrel.ss.v1", "ts": 0,
///     "A": [[0, 1], [0, 0]], "B": [[0], [1]], "C": [[1, 0]], "D": [[0]]}"#).unwrap();
/// let d = m.c2d(0.02).unwrap();
/// assert_eq!(d.ts, 0.02);
/// assert!((d.b[(0, 0)] - 0.0002).abs() < 1e-15);
/// let back = SsModel::from_json_str(&d.to_json_string()).unwrap();
/// assert_eq!(back, d);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct SsModel {
    /// Sample time in seconds; 0 for continuous time.
    pub ts: f64,
    /// State matrix, `nx x nx`.
    pub a: DMatrix<f64>,
    /// Input matrix, `nx x nu`.
    pub b: DMatrix<f64>,
    /// Output matrix, `ny x nx`.
    pub c: DMatrix<f64>,
    /// Feed-through, `ny x nu` (zeros when absent from the file).
    pub d: DMatrix<f64>,
    /// Innovation gain, `nx x ny`.
    pub k: Option<DMatrix<f64>>,
    /// Initial state.
    pub x0: Option<DVector<f64>>,
    /// Input operating point.
    pub u0: Option<DVector<f64>>,
    /// Output operating point.
    pub y0: Option<DVector<f64>>,
    /// Input names.
    pub inputs: Option<Vec<String>>,
    /// Output names.
    pub outputs: Option<Vec<String>>,
}

impl SsModel {
    /// The format name.
    pub const FORMAT: &'static str = "kestrel.ss.v1";

    /// A model from its four matrices, checking shapes and finiteness.
    pub fn new(
        ts: f64,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
    ) -> Result<Self, FormatError> {
        let m = SsModel {
            ts,
            a,
            b,
            c,
            d,
            k: None,
            x0: None,
            u0: None,
            y0: None,
            inputs: None,
            outputs: None,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks every shape and value against the format's rules.
    pub fn validate(&self) -> Result<(), FormatError> {
        let shape = |key: &str, want: (usize, usize), m: &DMatrix<f64>| {
            if m.shape() != want {
                return Err(FormatError::Shape {
                    key: key.into(),
                    expected: format!("a {} x {} matrix", want.0, want.1),
                    found: format!("a {} x {} matrix", m.nrows(), m.ncols()),
                });
            }
            if let Some(i) = m.iter().position(|v| !v.is_finite()) {
                return Err(FormatError::NonFinite {
                    key: format!("{key}[{}][{}]", i % m.nrows(), i / m.nrows()),
                    found: m[i].to_string(),
                });
            }
            Ok(())
        };
        if !(self.ts.is_finite() && self.ts >= 0.0) {
            return Err(FormatError::invalid(
                "ts",
                format!("must be finite and >= 0, found {}", self.ts),
            ));
        }
        let (nx, nu, ny) = (self.a.nrows(), self.b.ncols(), self.c.nrows());
        shape("A", (nx, nx), &self.a)?;
        shape("B", (nx, nu), &self.b)?;
        shape("C", (ny, nx), &self.c)?;
        shape("D", (ny, nu), &self.d)?;
        if let Some(k) = &self.k {
            shape("K", (nx, ny), k)?;
        }
        for (key, v, n) in [
            ("x0", &self.x0, nx),
            ("u0", &self.u0, nu),
            ("y0", &self.y0, ny),
        ] {
            if let Some(v) = v {
                shape(
                    key,
                    (n, 1),
                    &DMatrix::from_column_slice(v.len(), 1, v.as_slice()),
                )?;
            }
        }
        for (key, names, n) in [("inputs", &self.inputs, nu), ("outputs", &self.outputs, ny)] {
            if let Some(names) = names
                && names.len() != n
            {
                return Err(FormatError::Shape {
                    key: key.into(),
                    expected: format!("an array of {n} strings"),
                    found: format!("{} entries", names.len()),
                });
            }
        }
        Ok(())
    }

    /// Number of states.
    pub fn nx(&self) -> usize {
        self.a.nrows()
    }
    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.b.ncols()
    }
    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.c.nrows()
    }

    /// Reads a model from a parsed JSON object. A missing `D` is zero (an
    /// error above 2^20 entries: give `D` in the file).
    pub fn from_object(obj: &Object) -> Result<Self, FormatError> {
        json::check_format(obj, Self::FORMAT)?;
        let ts = json::number(obj, "ts")?;
        let a = json::square_matrix(obj, "A")?;
        let nx = a.nrows();
        let b = json::matrix(obj, "B", Some(nx), None)?;
        let nu = b.ncols();
        let c = json::matrix(obj, "C", None, Some(nx))?;
        let ny = c.nrows();
        let d = match json::opt_matrix(obj, "D", Some(ny), Some(nu))? {
            Some(d) => d,
            None => default_d(ny, nu)?,
        };
        let m = SsModel {
            ts,
            a,
            b,
            c,
            d,
            k: json::opt_matrix(obj, "K", Some(nx), Some(ny))?,
            x0: json::opt_vector(obj, "x0", Some(nx))?,
            u0: json::opt_vector(obj, "u0", Some(nu))?,
            y0: json::opt_vector(obj, "y0", Some(ny))?,
            inputs: json::opt_strings(obj, "inputs", Some(nu))?,
            outputs: json::opt_strings(obj, "outputs", Some(ny))?,
        };
        m.validate()?;
        Ok(m)
    }

    /// Reads a model from JSON text.
    pub fn from_json_str(text: &str) -> Result<Self, FormatError> {
        Self::from_object(&json::parse_object(text)?)
    }

    /// Reads a model from a file.
    pub fn read(path: &std::path::Path) -> Result<Self, FormatError> {
        Self::from_json_str(&super::read_text(path)?)
    }

    /// The model as a JSON object.
    pub fn to_object(&self) -> Object {
        let mut o = Object::new();
        o.insert("format".into(), Self::FORMAT.into());
        o.insert("ts".into(), Value::from(self.ts));
        o.insert("A".into(), json::matrix_to_value(&self.a));
        o.insert("B".into(), json::matrix_to_value(&self.b));
        o.insert("C".into(), json::matrix_to_value(&self.c));
        o.insert("D".into(), json::matrix_to_value(&self.d));
        if let Some(k) = &self.k {
            o.insert("K".into(), json::matrix_to_value(k));
        }
        for (key, v) in [("x0", &self.x0), ("u0", &self.u0), ("y0", &self.y0)] {
            if let Some(v) = v {
                o.insert(key.into(), json::vector_to_value(v));
            }
        }
        for (key, v) in [("inputs", &self.inputs), ("outputs", &self.outputs)] {
            if let Some(v) = v {
                o.insert(key.into(), Value::from(v.clone()));
            }
        }
        o
    }

    /// The model as readable JSON text.
    pub fn to_json_string(&self) -> String {
        json::to_pretty_string(&self.to_object())
    }

    /// Zero-order-hold discretisation of a continuous-time model (see [`linalg::c2d`]).
    ///
    /// `C`, `D`, the operating point, `x0` and the names carry over. A
    /// continuous-time innovation gain has no zero-order-hold equivalent,
    /// so a model with `K` is refused.
    pub fn c2d(&self, ts: f64) -> Result<SsModel, FormatError> {
        if self.ts != 0.0 {
            return Err(FormatError::invalid(
                "ts",
                format!(
                    "c2d needs a continuous-time model (ts = 0), found ts = {}",
                    self.ts
                ),
            ));
        }
        if self.k.is_some() {
            return Err(FormatError::invalid(
                "K",
                "a continuous-time innovation gain cannot be discretised by zero-order hold; remove it",
            ));
        }
        let d = linalg::c2d(&self.a, &self.b, ts).map_err(|e| match e {
            Error::InvalidArgument(_) => FormatError::invalid(
                "ts",
                format!("sample time must be finite and > 0, found {ts}"),
            ),
            other => FormatError::invalid("A", format!("discretisation failed: {other}")),
        })?;
        Ok(SsModel {
            ts,
            a: d.a,
            b: d.b,
            ..self.clone()
        })
    }
}

impl DiscreteLinearModel for SsModel {
    type Scalar = f64;
    fn nx(&self) -> usize {
        self.a.nrows()
    }
    fn nu(&self) -> usize {
        self.b.ncols()
    }
    fn ny(&self) -> usize {
        self.c.nrows()
    }
    fn sample_time(&self) -> f64 {
        self.ts
    }
    fn a(&self, i: usize, j: usize) -> f64 {
        self.a.get((i, j)).copied().unwrap_or(0.0)
    }
    fn b(&self, i: usize, j: usize) -> f64 {
        self.b.get((i, j)).copied().unwrap_or(0.0)
    }
    fn c(&self, i: usize, j: usize) -> f64 {
        self.c.get((i, j)).copied().unwrap_or(0.0)
    }
    fn d(&self, i: usize, j: usize) -> f64 {
        self.d.get((i, j)).copied().unwrap_or(0.0)
    }
}

/// Entries of the zero `D` a file without `D` gets at most (8 MiB): memory
/// follows the text, so a short file cannot claim a huge default.
const MAX_DEFAULT_D: usize = 1 << 20;

/// The zero `D` of a file without `D` (ny x nu, at most [`MAX_DEFAULT_D`]
/// entries).
fn default_d(ny: usize, nu: usize) -> Result<DMatrix<f64>, FormatError> {
    if ny.saturating_mul(nu) > MAX_DEFAULT_D {
        return Err(FormatError::invalid(
            "D",
            format!(
                "missing, and its default, a {ny} x {nu} zero matrix, is above {MAX_DEFAULT_D} entries; give D in the file"
            ),
        ));
    }
    Ok(DMatrix::zeros(ny, nu))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"format": "kestrel.ss.v1", "ts": 0.02,
        "A": [[0.9, 0.1], [0, 0.8]], "B": [[0], [1]], "C": [[1, 0]], "D": [[0]],
        "K": [[0.1], [0.2]], "x0": [0, 0], "u0": [1500], "y0": [0.1],
        "inputs": ["pwm"], "outputs": ["p"]}"#;

    fn with(key: &str, value: &str) -> String {
        let mut obj = json::parse_object(GOOD).unwrap();
        if value.is_empty() {
            obj.remove(key);
        } else {
            obj.insert(key.into(), serde_json::from_str(value).unwrap());
        }
        serde_json::to_string(&obj).unwrap()
    }

    /// Found with the fuzz targets' size check: a model without `D` got a default
    /// zero matrix of ny x nu, so 50,000 inputs in `B` and 50,000 outputs
    /// in `C` (300 kB of text) asked for a 20 GB `D`.
    #[test]
    fn a_missing_d_is_not_a_huge_default() {
        let n = 50_000;
        let text = format!(
            r#"{{"format": "kestrel.ss.v1", "ts": 0.02, "A": [[0.5]], "B": [[{}]], "C": [{}]}}"#,
            vec!["0"; n].join(","),
            vec!["[0]"; n].join(",")
        );
        let e = SsModel::from_json_str(&text).unwrap_err().to_string();
        assert!(e.contains("\"D\"") && e.contains("50000 x 50000"), "{e}");
        let small = with("D", "");
        let m = SsModel::from_json_str(&small).unwrap();
        assert_eq!(m.d, DMatrix::zeros(1, 1));
    }

    #[test]
    fn reads_and_round_trips() {
        let m = SsModel::from_json_str(GOOD).unwrap();
        assert_eq!((m.nx(), m.nu(), m.ny()), (2, 1, 1));
        assert_eq!(m.u0.as_ref().unwrap()[0], 1500.0);
        assert_eq!(SsModel::from_json_str(&m.to_json_string()).unwrap(), m);
        let mut xn = [0.0; 2];
        m.step_into(&[1.0, 1.0], &[1.0], &mut xn).unwrap();
        assert!((xn[0] - 1.0).abs() < 1e-15 && (xn[1] - 1.8).abs() < 1e-15);
    }

    #[test]
    fn errors_name_key_and_shape() {
        let cases = [
            (
                with("format", r#""kestrel.ss.v2""#),
                "key \"format\": expected \"kestrel.ss.v1\"",
            ),
            (with("format", ""), "missing key \"format\""),
            (with("A", ""), "missing key \"A\""),
            (
                with("A", "[[1, 2]]"),
                "key \"A\": expected a square matrix, found a 1 x 2 matrix",
            ),
            (with("B", "[[1]]"), "key \"B\": expected a 2 x n matrix"),
            (
                with("C", "[[1, 0, 0]]"),
                "key \"C\": expected a n x 2 matrix",
            ),
            (with("D", "[[0, 0]]"), "key \"D\": expected a 1 x 1 matrix"),
            (with("K", "[[1, 2]]"), "key \"K\": expected a 2 x 1 matrix"),
            (
                with("x0", "[1]"),
                "key \"x0\": expected a vector of 2 numbers",
            ),
            (
                with("u0", "[1, 2]"),
                "key \"u0\": expected a vector of 1 numbers",
            ),
            (
                with("inputs", r#"["a", "b"]"#),
                "key \"inputs\": expected an array of 1 strings",
            ),
            (with("ts", "-1"), "key \"ts\": must be finite and >= 0"),
            (
                with("ts", r#""NaN""#),
                "key \"ts\": expected a finite number, found NaN",
            ),
        ];
        for (text, want) in cases {
            let e = SsModel::from_json_str(&text).unwrap_err().to_string();
            assert!(e.starts_with(want), "got {e:?}, want prefix {want:?}");
        }
        let nan = GOOD.replace("[[0.9, 0.1]", "[[NaN, 0.1]");
        let e = SsModel::from_json_str(&nan).unwrap_err().to_string();
        assert_eq!(e, "key \"A[0][0]\": expected a finite number, found NaN");
    }

    #[test]
    fn d_defaults_to_zero() {
        let m = SsModel::from_json_str(&with("D", "")).unwrap();
        assert_eq!(m.d, DMatrix::zeros(1, 1));
    }

    #[test]
    fn c2d_rules() {
        let m = SsModel::from_json_str(GOOD).unwrap();
        assert!(
            m.c2d(0.01)
                .unwrap_err()
                .to_string()
                .contains("continuous-time")
        );
        let mut c = m.clone();
        c.ts = 0.0;
        assert!(c.c2d(0.01).unwrap_err().to_string().contains("\"K\""));
        c.k = None;
        assert!(c.c2d(0.0).unwrap_err().to_string().contains("\"ts\""));
        let d = c.c2d(0.01).unwrap();
        assert_eq!(d.c, c.c);
        assert_eq!(d.u0, c.u0);
        let mut bad = c.clone();
        bad.a[(0, 0)] = f64::INFINITY;
        assert!(bad.validate().is_err());
    }
}
