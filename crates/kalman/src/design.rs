//! Stationary filter design from a `kestrel.ss.v1` model, the
//! `kestrel.kalman.v1` file, and the conversion to run-time tables (feature `std`).

use crate::dare::check_shape;
use crate::stationary::{StationaryFilter, StationaryGains};
use crate::{DareSettings, Dlqe, KalmanError, dlqe_with};
use kestrel_core::Matrix;
use kestrel_core::Scalar;
use kestrel_core::formats::json::{self, Object};
use kestrel_core::formats::{FormatError, SsModel};
use nalgebra::{DMatrix, DVector};
use serde_json::Value;

/// The noise model of a filter design: `x+ = A x + B u + G w`,
/// `y = C x + D u + b + v`, `Cov(w) = Q`, `Cov(v) = R`, `E[w v'] = N`.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseModel {
    /// How the process noise enters, `nx x nw`; `None` means the identity.
    pub g: Option<DMatrix<f64>>,
    /// Process noise covariance `Q`, `nw x nw`.
    pub q: DMatrix<f64>,
    /// Measurement noise covariance `R`, `ny x ny` (thesis (7.6) for the gyro).
    pub r: DMatrix<f64>,
    /// Cross-covariance `N`, `nw x ny`.
    pub cross: Option<DMatrix<f64>>,
    /// Known constant sensor bias `b` (thesis (7.5), `e_0`), `ny`.
    pub bias: Option<DVector<f64>>,
}

impl NoiseModel {
    /// `Q = q I` (process noise through the identity) and `R = r I`.
    pub fn isotropic(nx: usize, ny: usize, q: f64, r: f64) -> Self {
        NoiseModel {
            g: None,
            q: DMatrix::identity(nx, nx) * q,
            r: DMatrix::identity(ny, ny) * r,
            cross: None,
            bias: None,
        }
    }

    /// The noise model of an identified model in innovations form,
    /// `x+ = A x + B u + K e`, `y = C x + D u + e`, `Cov(e) = re` (what
    /// kestrel-sysid's PEM estimates): the innovation `e` is both the
    /// process noise, entering through `G = K`, and the measurement noise,
    /// so `Q = R = N = re`.
    ///
    /// The stationary filter of this model has the error covariance `P = 0`
    /// and the predictor gain `L = K` whenever `A - K C` is stable (the
    /// model's own one-step predictor), for any positive definite `re`; its
    /// measurement-update gain is `M = 0` and the gain reaches the state
    /// through the cross term. If `A - K C` is not stable (a noise model
    /// that is not minimum phase), the noise `K e` with `e` also the
    /// measurement noise reaches none of its unstable modes and the design
    /// fails ([`KalmanError::NotStabilizable`] naming the mode of `A - K C`,
    /// or [`KalmanError::NoStabilizingSolution`] for a mode on the unit
    /// circle).
    ///
    /// ```
    /// use kestrel_core::formats::SsModel;
    /// use kestrel_kalman::{KalmanDesign, NoiseModel};
    /// use nalgebra::{DMatrix, dmatrix};
    /// let model = SsModel::from_json_str(r#"{"format": "kestrel.ss.v1", "ts": 0.02,
    ///     "A": [[0.9, 0.1], [0, 0.8]], "B": [[0], [1]], "C": [[1, 0]], "D": [[0]]}"#).unwrap();
    /// let k = dmatrix![0.5; 0.2];
    /// let noise = NoiseModel::innovations(&k, &DMatrix::identity(1, 1));
    /// let design = KalmanDesign::new(&model, &noise).unwrap();
    /// assert!((&design.filter.l - &k).norm() < 1e-12);
    /// ```
    pub fn innovations(k: &DMatrix<f64>, re: &DMatrix<f64>) -> Self {
        NoiseModel {
            g: Some(k.clone()),
            q: re.clone(),
            r: re.clone(),
            cross: Some(re.clone()),
            bias: None,
        }
    }
}

/// A designed stationary Kalman filter: the model, the noise model and the
/// gains; what `kestrel kalman` writes as `kestrel.kalman.v1`.
#[derive(Clone, Debug, PartialEq)]
pub struct KalmanDesign {
    /// Sample time in seconds.
    pub ts: f64,
    /// State matrix.
    pub a: DMatrix<f64>,
    /// Input matrix.
    pub b: DMatrix<f64>,
    /// Output matrix.
    pub c: DMatrix<f64>,
    /// Feed-through.
    pub d: DMatrix<f64>,
    /// Process-noise input matrix (the identity when the design had none).
    pub g: DMatrix<f64>,
    /// Process noise covariance.
    pub q: DMatrix<f64>,
    /// Measurement noise covariance.
    pub r: DMatrix<f64>,
    /// Cross-covariance, if any.
    pub cross: Option<DMatrix<f64>>,
    /// Input operating point (zeros when the model has none).
    pub u0: DVector<f64>,
    /// Output operating point (zeros when the model has none).
    pub y0: DVector<f64>,
    /// Sensor bias (zeros when none was given).
    pub bias: DVector<f64>,
    /// The stationary gains (`M`, `L`, `P`, `Z`, ...).
    pub filter: Dlqe,
}

impl KalmanDesign {
    /// The file format name.
    pub const FORMAT: &'static str = "kestrel.kalman.v1";

    /// Designs the stationary filter for a discrete model (`ts > 0`).
    ///
    /// ```
    /// use kestrel_core::formats::SsModel;
    /// use kestrel_kalman::{KalmanDesign, NoiseModel};
    /// let model = SsModel::from_json_str(r#"{"format": "kestrel.ss.v1", "ts": 0.02,
    ///     "A": [[1, 0.02], [0, 1]], "B": [[0.0002], [0.02]], "C": [[1, 0]], "D": [[0]]}"#).unwrap();
    /// let design = KalmanDesign::new(&model, &NoiseModel::isotropic(2, 1, 1e-4, 1e-2)).unwrap();
    /// let back = KalmanDesign::from_json_str(&design.to_json_string()).unwrap();
    /// assert!((back.filter.m - &design.filter.m).norm() < 1e-15);
    /// let filter = design.filter::<f32, 2, 1, 1>().unwrap();
    /// assert_eq!(filter.gains().multiply_adds(), 2 + 2 + 4 + 2);
    /// ```
    pub fn new(model: &SsModel, noise: &NoiseModel) -> Result<Self, KalmanError> {
        Self::with_settings(model, noise, &DareSettings::default())
    }

    /// [`KalmanDesign::new`] with explicit Riccati settings.
    pub fn with_settings(
        model: &SsModel,
        noise: &NoiseModel,
        settings: &DareSettings,
    ) -> Result<Self, KalmanError> {
        if !(model.ts.is_finite() && model.ts > 0.0) {
            return Err(KalmanError::InvalidArgument {
                name: "ts",
                reason: format!(
                    "the model must be discrete (ts > 0), found ts = {}",
                    model.ts
                ),
            });
        }
        let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
        check_shape("A", &model.a, nx, nx)?;
        check_shape("B", &model.b, nx, nu)?;
        check_shape("C", &model.c, ny, nx)?;
        check_shape("D", &model.d, ny, nu)?;
        let g = noise.g.clone().unwrap_or_else(|| DMatrix::identity(nx, nx));
        let bias = match &noise.bias {
            Some(b) => {
                let bm = DMatrix::from_column_slice(b.len(), 1, b.as_slice());
                check_shape("bias", &bm, ny, 1)?;
                b.clone()
            }
            None => DVector::zeros(ny),
        };
        let filter = dlqe_with(
            &model.a,
            &g,
            &model.c,
            &noise.q,
            &noise.r,
            noise.cross.as_ref(),
            settings,
        )?;
        Ok(KalmanDesign {
            ts: model.ts,
            a: model.a.clone(),
            b: model.b.clone(),
            c: model.c.clone(),
            d: model.d.clone(),
            g,
            q: noise.q.clone(),
            r: noise.r.clone(),
            cross: noise.cross.clone(),
            u0: model.u0.clone().unwrap_or_else(|| DVector::zeros(nu)),
            y0: model.y0.clone().unwrap_or_else(|| DVector::zeros(ny)),
            bias,
            filter,
        })
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

    /// The folded run-time tables in scalar `S`, checking the const dimensions.
    pub fn gains<S: Scalar, const NX: usize, const NU: usize, const NY: usize>(
        &self,
    ) -> Result<StationaryGains<S, NX, NU, NY>, KalmanError> {
        let (cross, use_d, use_cross) = self.folded();
        let offset = &self.y0 + &self.bias;
        Ok(StationaryGains {
            a: Matrix::try_from_dmatrix(&self.a)?,
            b: Matrix::try_from_dmatrix(&self.b)?,
            c: Matrix::try_from_dmatrix(&self.c)?,
            d: Matrix::try_from_dmatrix(&self.d)?,
            m: Matrix::try_from_dmatrix(&self.filter.m)?,
            cross: if use_cross {
                Matrix::try_from_dmatrix(&cross)?
            } else {
                Matrix::zeros()
            },
            u0: to_array(&self.u0)?,
            y0: to_array(&self.y0)?,
            y_offset: to_array(&offset)?,
            use_d,
            use_cross,
        })
    }

    /// The innovation correction `L - A M` of the time update and whether
    /// the run-time step uses `D` and that correction.
    fn folded(&self) -> (DMatrix<f64>, bool, bool) {
        let cross = &self.filter.l - &self.a * &self.filter.m;
        let scale = self.filter.l.norm().max(f64::MIN_POSITIVE);
        let use_cross = cross.norm() > 1e-14 * scale;
        let use_d = self.d.iter().any(|v| *v != 0.0);
        (cross, use_d, use_cross)
    }

    /// Multiply-adds of one run-time step (measurement plus time update) of
    /// the folded stationary filter: `2 nx ny + nx^2 + nx nu`, plus `ny nu`
    /// with a non-zero `D` and `nx ny` with cross-covariance; the same
    /// count as [`StationaryGains::multiply_adds`], without the const
    /// dimensions. 75 for 5 states, 4 inputs, 3 outputs.
    pub fn multiply_adds(&self) -> usize {
        let (nx, nu, ny) = (self.nx(), self.nu(), self.ny());
        let (_, use_d, use_cross) = self.folded();
        2 * nx * ny
            + nx * nx
            + nx * nu
            + if use_d { ny * nu } else { 0 }
            + if use_cross { nx * ny } else { 0 }
    }

    /// A run-time filter in scalar `S`, starting from the operating point (`x = 0`).
    pub fn filter<S: Scalar, const NX: usize, const NU: usize, const NY: usize>(
        &self,
    ) -> Result<StationaryFilter<S, NX, NU, NY>, KalmanError> {
        Ok(StationaryFilter::new(self.gains()?, [S::ZERO; NX]))
    }

    /// The design as a `kestrel.kalman.v1` JSON object.
    pub fn to_object(&self) -> Object {
        let mut o = Object::new();
        o.insert("format".into(), Self::FORMAT.into());
        o.insert("ts".into(), Value::from(self.ts));
        for (key, m) in [
            ("A", &self.a),
            ("B", &self.b),
            ("C", &self.c),
            ("D", &self.d),
            ("G", &self.g),
            ("Q", &self.q),
            ("R", &self.r),
        ] {
            o.insert(key.into(), json::matrix_to_value(m));
        }
        if let Some(n) = &self.cross {
            o.insert("N".into(), json::matrix_to_value(n));
        }
        for (key, v) in [("u0", &self.u0), ("y0", &self.y0), ("bias", &self.bias)] {
            o.insert(key.into(), json::vector_to_value(v));
        }
        for (key, m) in [
            ("M", &self.filter.m),
            ("L", &self.filter.l),
            ("P", &self.filter.p),
            ("Z", &self.filter.z),
        ] {
            o.insert(key.into(), json::matrix_to_value(m));
        }
        o.insert(
            "eigenvalues".into(),
            Value::Array(
                self.filter
                    .closed_loop_eigenvalues
                    .iter()
                    .map(|z| Value::Array(vec![Value::from(z.re), Value::from(z.im)]))
                    .collect(),
            ),
        );
        o.insert("residual".into(), Value::from(self.filter.residual));
        o.insert("multiply_adds".into(), Value::from(self.multiply_adds()));
        o
    }

    /// The design as readable JSON text.
    pub fn to_json_string(&self) -> String {
        json::to_pretty_string(&self.to_object())
    }

    /// Reads a design from a parsed `kestrel.kalman.v1` object. The stored
    /// gains are read as they are (not recomputed); shapes are checked
    /// against `A`, `B`, `C`.
    pub fn from_object(obj: &Object) -> Result<Self, FormatError> {
        json::check_format(obj, Self::FORMAT)?;
        let ts = json::number(obj, "ts")?;
        let a = json::square_matrix(obj, "A")?;
        let nx = a.nrows();
        let b = json::matrix(obj, "B", Some(nx), None)?;
        let nu = b.ncols();
        let c = json::matrix(obj, "C", None, Some(nx))?;
        let ny = c.nrows();
        let d = json::matrix(obj, "D", Some(ny), Some(nu))?;
        let g = json::matrix(obj, "G", Some(nx), None)?;
        let nw = g.ncols();
        let q = json::matrix(obj, "Q", Some(nw), Some(nw))?;
        let r = json::matrix(obj, "R", Some(ny), Some(ny))?;
        let cross = json::opt_matrix(obj, "N", Some(nw), Some(ny))?;
        let u0 = json::vector(obj, "u0", Some(nu))?;
        let y0 = json::vector(obj, "y0", Some(ny))?;
        let bias = json::vector(obj, "bias", Some(ny))?;
        let m = json::matrix(obj, "M", Some(nx), Some(ny))?;
        let l = json::matrix(obj, "L", Some(nx), Some(ny))?;
        let p = json::matrix(obj, "P", Some(nx), Some(nx))?;
        let z = json::matrix(obj, "Z", Some(nx), Some(nx))?;
        let eig = json::matrix(obj, "eigenvalues", Some(nx), Some(2))?;
        let residual = json::number(obj, "residual")?;
        let innovation_covariance = &c * &p * c.transpose() + &r;
        Ok(KalmanDesign {
            ts,
            a,
            b,
            c,
            d,
            g,
            q,
            r,
            cross,
            u0,
            y0,
            bias,
            filter: Dlqe {
                m,
                l,
                p,
                z,
                innovation_covariance,
                closed_loop_eigenvalues: DVector::from_fn(nx, |i, _| {
                    nalgebra::Complex::new(eig[(i, 0)], eig[(i, 1)])
                }),
                residual,
            },
        })
    }

    /// Reads a design from JSON text.
    pub fn from_json_str(text: &str) -> Result<Self, FormatError> {
        Self::from_object(&json::parse_object(text)?)
    }

    /// Reads a design from a file.
    pub fn read(path: &std::path::Path) -> Result<Self, FormatError> {
        Self::from_json_str(&kestrel_core::formats::read_text(path)?)
    }
}

fn to_array<const N: usize, S: Scalar>(v: &DVector<f64>) -> Result<[S; N], KalmanError> {
    if v.len() != N {
        return Err(KalmanError::Core(kestrel_core::Error::DimensionMismatch {
            expected: N,
            found: v.len(),
        }));
    }
    Ok(core::array::from_fn(|i| S::from_f64(v[i])))
}
