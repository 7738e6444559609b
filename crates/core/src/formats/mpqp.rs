//! `kestrel.mpqp.v1`: a multi-parametric quadratic program.

#[allow(unused_imports)]
use std::{borrow::ToOwned, format, string::String, string::ToString, vec, vec::Vec};

use super::json::{self, Object};
use super::{FormatError, SsModel};
use nalgebra::{DMatrix, DVector};

/// A multi-parametric QP in the thesis form (6.19)-(6.21):
///
/// minimise over `z`: `1/2 z'Hz + (F'theta + f)'z`
/// subject to `G z <= W + E theta`, `theta_lb <= theta <= theta_ub`
/// and, optionally, `theta_A theta <= theta_b`.
///
/// `n` decision variables, `p` parameters, `m` constraints.
///
/// ```
/// use kestrel_core::formats::MpqpProblem;
/// let p = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
///   "H": [[2]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
///   "theta_lb": [-5], "theta_ub": [5]}"#).unwrap();
/// assert_eq!((p.n(), p.p(), p.m()), (1, 1, 2));
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct MpqpProblem {
    /// Hessian, `n x n`, symmetric.
    pub h: DMatrix<f64>,
    /// Parameter-to-linear-term map, `p x n`.
    pub f_theta: DMatrix<f64>,
    /// Constant linear term, `n`.
    pub f: DVector<f64>,
    /// Constraint matrix, `m x n`.
    pub g: DMatrix<f64>,
    /// Constraint right-hand side, `m`.
    pub w: DVector<f64>,
    /// Parameter dependence of the right-hand side, `m x p`.
    pub e: DMatrix<f64>,
    /// Lower bounds of the parameter box, `p`.
    pub theta_lb: DVector<f64>,
    /// Upper bounds of the parameter box, `p`.
    pub theta_ub: DVector<f64>,
    /// Optional extra parameter polytope `theta_A theta <= theta_b`: (`q x p`, `q`).
    pub theta_poly: Option<(DMatrix<f64>, DVector<f64>)>,
}

impl MpqpProblem {
    /// The format name.
    pub const FORMAT: &'static str = "kestrel.mpqp.v1";

    /// Number of decision variables.
    pub fn n(&self) -> usize {
        self.h.nrows()
    }
    /// Number of parameters.
    pub fn p(&self) -> usize {
        self.f_theta.nrows()
    }
    /// Number of constraints.
    pub fn m(&self) -> usize {
        self.g.nrows()
    }

    /// Checks shapes, finiteness, symmetry of `H` and the parameter box.
    /// (Positive definiteness is the solvers' check.)
    pub fn validate(&self) -> Result<(), FormatError> {
        let (n, p, m) = (self.n(), self.p(), self.m());
        let check = |key: &str, rows: usize, cols: usize, mat: &DMatrix<f64>| {
            if mat.shape() != (rows, cols) {
                return Err(FormatError::Shape {
                    key: key.into(),
                    expected: format!("a {rows} x {cols} matrix"),
                    found: format!("a {} x {} matrix", mat.nrows(), mat.ncols()),
                });
            }
            match mat.iter().position(|v| !v.is_finite()) {
                Some(i) => Err(FormatError::NonFinite {
                    key: format!("{key}[{}][{}]", i % rows.max(1), i / rows.max(1)),
                    found: mat[i].to_string(),
                }),
                None => Ok(()),
            }
        };
        let vcheck = |key: &str, len: usize, v: &DVector<f64>| {
            check(
                key,
                len,
                1,
                &DMatrix::from_column_slice(v.len(), 1, v.as_slice()),
            )
            .map_err(|e| match e {
                FormatError::Shape { key, .. } => FormatError::Shape {
                    key,
                    expected: format!("a vector of {len} numbers"),
                    found: format!("{} entries", v.len()),
                },
                other => other,
            })
        };
        check("H", n, n, &self.h)?;
        check("F", p, n, &self.f_theta)?;
        vcheck("f", n, &self.f)?;
        check("G", m, n, &self.g)?;
        vcheck("W", m, &self.w)?;
        check("E", m, p, &self.e)?;
        vcheck("theta_lb", p, &self.theta_lb)?;
        vcheck("theta_ub", p, &self.theta_ub)?;
        let asym = (&self.h - self.h.transpose()).amax();
        if asym > 1e-9 * self.h.amax().max(1.0) {
            return Err(FormatError::invalid(
                "H",
                format!("must be symmetric (largest asymmetry {asym:e})"),
            ));
        }
        if let Some(i) = (0..p).find(|&i| self.theta_lb[i] > self.theta_ub[i]) {
            return Err(FormatError::invalid(
                "theta_lb",
                format!(
                    "entry {i} ({}) exceeds theta_ub[{i}] ({})",
                    self.theta_lb[i], self.theta_ub[i]
                ),
            ));
        }
        if let Some((a, b)) = &self.theta_poly {
            check("theta_A", a.nrows(), p, a)?;
            vcheck("theta_b", a.nrows(), b)?;
        }
        Ok(())
    }

    /// Reads a problem from a parsed JSON object.
    pub fn from_object(obj: &Object) -> Result<Self, FormatError> {
        json::check_format(obj, Self::FORMAT)?;
        let h = json::square_matrix(obj, "H")?;
        let n = h.nrows();
        let f_theta = json::matrix(obj, "F", None, Some(n))?;
        let p = f_theta.nrows();
        let f = json::opt_vector(obj, "f", Some(n))?.unwrap_or_else(|| DVector::zeros(n));
        let g = json::matrix(obj, "G", None, Some(n))?;
        let m = g.nrows();
        let w = json::vector(obj, "W", Some(m))?;
        let e = json::matrix(obj, "E", Some(m), Some(p))?;
        let theta_lb = json::vector(obj, "theta_lb", Some(p))?;
        let theta_ub = json::vector(obj, "theta_ub", Some(p))?;
        let theta_poly = match json::opt_matrix(obj, "theta_A", None, Some(p))? {
            Some(a) => {
                let b = json::vector(obj, "theta_b", Some(a.nrows()))?;
                Some((a, b))
            }
            None => {
                if obj.contains_key("theta_b") {
                    return Err(FormatError::MissingKey {
                        key: "theta_A".into(),
                        expected: format!("a q x {p} matrix to go with \"theta_b\""),
                    });
                }
                None
            }
        };
        let prob = MpqpProblem {
            h,
            f_theta,
            f,
            g,
            w,
            e,
            theta_lb,
            theta_ub,
            theta_poly,
        };
        prob.validate()?;
        Ok(prob)
    }

    /// Reads a problem from JSON text.
    pub fn from_json_str(text: &str) -> Result<Self, FormatError> {
        Self::from_object(&json::parse_object(text)?)
    }

    /// Reads a problem from a file.
    pub fn read(path: &std::path::Path) -> Result<Self, FormatError> {
        Self::from_json_str(&super::read_text(path)?)
    }

    /// The problem as a JSON object.
    pub fn to_object(&self) -> Object {
        let mut o = Object::new();
        o.insert("format".into(), Self::FORMAT.into());
        o.insert("H".into(), json::matrix_to_value(&self.h));
        o.insert("F".into(), json::matrix_to_value(&self.f_theta));
        o.insert("f".into(), json::vector_to_value(&self.f));
        o.insert("G".into(), json::matrix_to_value(&self.g));
        o.insert("W".into(), json::vector_to_value(&self.w));
        o.insert("E".into(), json::matrix_to_value(&self.e));
        o.insert("theta_lb".into(), json::vector_to_value(&self.theta_lb));
        o.insert("theta_ub".into(), json::vector_to_value(&self.theta_ub));
        if let Some((a, b)) = &self.theta_poly {
            o.insert("theta_A".into(), json::matrix_to_value(a));
            o.insert("theta_b".into(), json::vector_to_value(b));
        }
        o
    }

    /// The problem as readable JSON text.
    pub fn to_json_string(&self) -> String {
        json::to_pretty_string(&self.to_object())
    }

    /// The linear term `F'theta + f` at a parameter value.
    pub fn linear_term(&self, theta: &DVector<f64>) -> DVector<f64> {
        self.f_theta.tr_mul(theta) + &self.f
    }

    /// The constraint right-hand side `W + E theta` at a parameter value.
    pub fn rhs(&self, theta: &DVector<f64>) -> DVector<f64> {
        &self.w + &self.e * theta
    }

    /// Scales the parameter box `[theta_lb, theta_ub]` by `factor` about its
    /// centre (e.g. `0.5`: half the width in every parameter).
    pub fn scale_parameter_box(&mut self, factor: f64) {
        for (lb, ub) in self.theta_lb.iter_mut().zip(self.theta_ub.iter_mut()) {
            let (c, h) = (0.5 * (*lb + *ub), 0.5 * factor * (*ub - *lb));
            *lb = c - h;
            *ub = c + h;
        }
    }
}

/// The model a problem was built on: the optional `model_fingerprint` key.
///
/// A condensed problem's parameters start with the state of the model it
/// was built on, so a filter or firmware that feeds it states must run the
/// same model in the same coordinates. `kestrel mpc` and `kestrel pipeline`
/// write the key; readers of the problem ignore it.
///
/// ```
/// use kestrel_core::formats::{MpqpProblem, SsModel, json};
/// use nalgebra::dmatrix;
/// let model = SsModel::new(0.1, dmatrix![0.9], dmatrix![0.1], dmatrix![1.0], dmatrix![0.0]).unwrap();
/// let p = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
///   "H": [[2]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
///   "theta_lb": [-5], "theta_ub": [5]}"#).unwrap();
/// let text = p.to_json_string_for_model(&model);
/// let obj = json::parse_object(&text).unwrap();
/// assert_eq!(MpqpProblem::from_object(&obj).unwrap(), p);
/// let fp = MpqpProblem::model_fingerprint_of(&obj).unwrap();
/// assert_eq!(fp, Some(MpqpProblem::model_fingerprint(&model)));
/// ```
impl MpqpProblem {
    /// The optional key holding [`MpqpProblem::model_fingerprint`].
    pub const MODEL_FINGERPRINT_KEY: &'static str = "model_fingerprint";

    /// A fingerprint of a model: FNV-1a (64 bit) over the sizes and the
    /// IEEE bits of the sample time, `A`, `B`, `C`, `D` (row by row) and
    /// `u0` (zeros when absent), written `fnv1a64:` and 16 hex digits.
    /// Models read from the same file get the same fingerprint; any other
    /// number in those matrices gives another. The output operating point,
    /// the names, `K` and `x0` are not part of it.
    pub fn model_fingerprint(model: &SsModel) -> String {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |word: u64| {
            for byte in word.to_le_bytes() {
                h = (h ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        // -0.0 and 0.0 are the same number.
        let bits = |v: f64| (v + 0.0).to_bits();
        for n in [model.nx(), model.nu(), model.ny()] {
            eat(n as u64);
        }
        eat(bits(model.ts));
        for m in [&model.a, &model.b, &model.c, &model.d] {
            for i in 0..m.nrows() {
                for j in 0..m.ncols() {
                    eat(bits(m[(i, j)]));
                }
            }
        }
        for i in 0..model.nu() {
            eat(bits(model.u0.as_ref().map_or(0.0, |u| u[i])));
        }
        format!("fnv1a64:{h:016x}")
    }

    /// The problem as JSON text with the fingerprint of the model it was
    /// built on (whose state is the leading part of `theta`).
    pub fn to_json_string_for_model(&self, model: &SsModel) -> String {
        let mut o = self.to_object();
        o.insert(
            Self::MODEL_FINGERPRINT_KEY.into(),
            Self::model_fingerprint(model).into(),
        );
        json::to_pretty_string(&o)
    }

    /// The model fingerprint a problem object carries, if any.
    ///
    /// # Errors
    /// [`FormatError::Invalid`] if the key holds something other than a string.
    pub fn model_fingerprint_of(obj: &Object) -> Result<Option<String>, FormatError> {
        match obj.get(Self::MODEL_FINGERPRINT_KEY) {
            None => Ok(None),
            Some(serde_json::Value::String(s)) => Ok(Some(s.clone())),
            Some(_) => Err(FormatError::invalid(
                Self::MODEL_FINGERPRINT_KEY,
                "expected a string (\"fnv1a64:\" and 16 hex digits)",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"format": "kestrel.mpqp.v1",
        "H": [[2, 0], [0, 1]], "F": [[1, 0], [0, 1], [1, 1]], "f": [0.5, 0],
        "G": [[1, 0], [-1, 0], [0, 1]], "W": [1, 1, 2], "E": [[0, 0, 1], [0, 0, 0], [1, 0, 0]],
        "theta_lb": [-1, -1, 0], "theta_ub": [1, 1, 1],
        "theta_A": [[1, 1, 0]], "theta_b": [1.5]}"#;

    #[test]
    fn reads_round_trips_and_evaluates() {
        let p = MpqpProblem::from_json_str(GOOD).unwrap();
        assert_eq!((p.n(), p.p(), p.m()), (2, 3, 3));
        assert_eq!(MpqpProblem::from_json_str(&p.to_json_string()).unwrap(), p);
        let th = DVector::from_vec(vec![1.0, 2.0, 3.0]);
        // F'theta + f = [1 + 3 + 0.5, 2 + 3].
        assert_eq!(p.linear_term(&th).as_slice(), &[4.5, 5.0]);
        // W + E theta = [1 + 3, 1, 2 + 1].
        assert_eq!(p.rhs(&th).as_slice(), &[4.0, 1.0, 3.0]);
    }

    #[test]
    fn scales_the_parameter_box_about_its_centre() {
        let mut p = MpqpProblem::from_json_str(GOOD).unwrap();
        p.scale_parameter_box(0.5);
        // [-1, 1] -> [-0.5, 0.5]; [0, 1] -> [0.25, 0.75].
        assert_eq!(p.theta_lb.as_slice(), &[-0.5, -0.5, 0.25]);
        assert_eq!(p.theta_ub.as_slice(), &[0.5, 0.5, 0.75]);
    }

    #[test]
    fn bad_files_name_key_and_shape() {
        let edit = |from: &str, to: &str| GOOD.replace(from, to);
        let cases = [
            (
                edit(r#""H": [[2, 0], [0, 1]]"#, r#""H": [[2, 1], [0, 1]]"#),
                "key \"H\": must be symmetric",
            ),
            (
                edit(r#""f": [0.5, 0]"#, r#""f": [0.5]"#),
                "key \"f\": expected a vector of 2 numbers",
            ),
            (
                edit(r#""W": [1, 1, 2]"#, r#""W": [1, 1]"#),
                "key \"W\": expected a vector of 3 numbers",
            ),
            (
                edit(r#""E": [[0, 0, 1],"#, r#""E": [[0, 0],"#),
                "key \"E\": expected a 3 x 3 matrix",
            ),
            (
                edit(r#""theta_lb": [-1, -1, 0]"#, r#""theta_lb": [-1, -1, 2]"#),
                "key \"theta_lb\": entry 2",
            ),
            (
                edit(r#""theta_ub": [1, 1, 1]"#, r#""theta_ub": [1, 1, NaN]"#),
                "key \"theta_ub[2]\": expected a finite number",
            ),
            (
                edit(r#""theta_A": [[1, 1, 0]], "#, ""),
                "missing key \"theta_A\"",
            ),
            (
                edit(r#""G": [[1, 0], [-1, 0], [0, 1]], "#, ""),
                "missing key \"G\"",
            ),
        ];
        for (text, want) in cases {
            let e = MpqpProblem::from_json_str(&text).unwrap_err().to_string();
            assert!(e.starts_with(want), "got {e:?}, want prefix {want:?}");
        }
    }

    #[test]
    fn model_fingerprint_tells_models_apart() {
        use nalgebra::dmatrix;
        let m = SsModel::new(
            0.1,
            dmatrix![0.9],
            dmatrix![0.1],
            dmatrix![1.0],
            dmatrix![0.0],
        )
        .unwrap();
        let fp = MpqpProblem::model_fingerprint(&m);
        assert_eq!(fp.len(), "fnv1a64:".len() + 16);
        assert_eq!(fp, MpqpProblem::model_fingerprint(&m.clone()));
        let mut other = m.clone();
        other.a[(0, 0)] = 0.9 + 1e-15;
        assert_ne!(MpqpProblem::model_fingerprint(&other), fp);
        let mut trim = m.clone();
        trim.u0 = Some(DVector::from_vec(vec![0.0]));
        assert_eq!(MpqpProblem::model_fingerprint(&trim), fp);
        trim.u0 = Some(DVector::from_vec(vec![1.0]));
        assert_ne!(MpqpProblem::model_fingerprint(&trim), fp);
        let mut ts = m.clone();
        ts.ts = 0.2;
        assert_ne!(MpqpProblem::model_fingerprint(&ts), fp);
        // Written and read back; absent in a plain file; not a string.
        let p = MpqpProblem::from_json_str(GOOD).unwrap();
        let obj = json::parse_object(&p.to_json_string_for_model(&m)).unwrap();
        assert_eq!(MpqpProblem::model_fingerprint_of(&obj).unwrap(), Some(fp));
        assert_eq!(MpqpProblem::from_object(&obj).unwrap(), p);
        let plain = json::parse_object(&p.to_json_string()).unwrap();
        assert_eq!(MpqpProblem::model_fingerprint_of(&plain).unwrap(), None);
        let bad =
            json::parse_object(&GOOD.replace("\"H\"", "\"model_fingerprint\": 3, \"H\"")).unwrap();
        let e = MpqpProblem::model_fingerprint_of(&bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("model_fingerprint"), "{e}");
    }
}
