//! The identified model: a discrete-time state-space model in innovation form.

use crate::error::{Result, SysidError};
use crate::linalg;
use kestrel_core::formats::SsModel;
use nalgebra::{Complex, DMatrix, DVector};

/// A discrete-time model in innovation form, (4.4) of the thesis with an
/// optional feed-through:
///
/// `x[k+1] = A x[k] + B u[k] + K e[k]`, `y[k] = C x[k] + D u[k] + e[k]`,
///
/// where `e` is the innovation (white, the one-step prediction error). The
/// deterministic part is `G(q) = C (qI - A)^-1 B + D` (4.7), the noise part
/// `H(q) = I + C (qI - A)^-1 K` (4.8). A model without a noise model has
/// `K = 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct InnovationModel {
    /// Sample time in seconds.
    pub ts: f64,
    /// State matrix, `nx x nx`.
    pub a: DMatrix<f64>,
    /// Input matrix, `nx x nu`.
    pub b: DMatrix<f64>,
    /// Output matrix, `ny x nx`.
    pub c: DMatrix<f64>,
    /// Feed-through, `ny x nu`.
    pub d: DMatrix<f64>,
    /// Innovation (Kalman) gain, `nx x ny`.
    pub k: DMatrix<f64>,
}

/// One-step-ahead prediction of a model on one experiment.
#[derive(Clone, Debug, PartialEq)]
pub struct OneStepPrediction {
    /// Predicted outputs `y(t|t-1)`, `N x ny`.
    pub yhat: DMatrix<f64>,
    /// Prediction errors (residuals) `y - yhat`, `N x ny`.
    pub residuals: DMatrix<f64>,
}

impl InnovationModel {
    /// A model from its matrices, checking shapes and finiteness.
    pub fn new(
        ts: f64,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        k: DMatrix<f64>,
    ) -> Result<Self> {
        let m = InnovationModel { ts, a, b, c, d, k };
        m.validate()?;
        Ok(m)
    }

    /// Checks shapes, finiteness and `ts > 0`.
    pub fn validate(&self) -> Result<()> {
        let (nx, nu, ny) = (self.a.nrows(), self.b.ncols(), self.c.nrows());
        let check = |what: &str, m: &DMatrix<f64>, r: usize, c: usize| -> Result<()> {
            if m.nrows() != r {
                return Err(SysidError::dim(format!("{what} rows"), r, m.nrows()));
            }
            if m.ncols() != c {
                return Err(SysidError::dim(format!("{what} columns"), c, m.ncols()));
            }
            if m.iter().any(|v| !v.is_finite()) {
                return Err(SysidError::invalid(format!(
                    "{what} has a non-finite entry"
                )));
            }
            Ok(())
        };
        check("A", &self.a, nx, nx)?;
        check("B", &self.b, nx, nu)?;
        check("C", &self.c, ny, nx)?;
        check("D", &self.d, ny, nu)?;
        check("K", &self.k, nx, ny)?;
        if !(self.ts.is_finite() && self.ts > 0.0) {
            return Err(SysidError::invalid(format!(
                "sample time must be finite and > 0, found {}",
                self.ts
            )));
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

    /// The poles (eigenvalues of `A`); an error when they cannot be
    /// computed (see [`linalg::eigenvalues`]).
    pub fn poles(&self) -> Result<Vec<Complex<f64>>> {
        linalg::eigenvalues(&self.a)
    }

    /// Spectral radius of `A` (the simulation model is stable when `< 1`).
    pub fn radius_a(&self) -> f64 {
        linalg::spectral_radius(&self.a)
    }

    /// Spectral radius of `A - K C` (the predictor is stable when `< 1`).
    pub fn radius_predictor(&self) -> f64 {
        linalg::spectral_radius(&(&self.a - &self.k * &self.c))
    }

    /// Simulates the deterministic part from state `x0`: `u` is `N x nu`,
    /// the result `N x ny`.
    pub fn simulate(&self, u: &DMatrix<f64>, x0: &DVector<f64>) -> Result<DMatrix<f64>> {
        self.check_io(u, None, x0)?;
        let n = u.nrows();
        let mut y = DMatrix::zeros(n, self.ny());
        let mut x = x0.clone();
        for t in 0..n {
            let ut = u.row(t).transpose();
            let yt = &self.c * &x + &self.d * &ut;
            y.row_mut(t).copy_from(&yt.transpose());
            x = &self.a * &x + &self.b * &ut;
        }
        Ok(y)
    }

    /// One-step-ahead predictor from state `x0`:
    /// `x[k+1] = (A - KC) x[k] + (B - KD) u[k] + K y[k]`, `yhat = C x + D u`.
    pub fn predict_one_step(
        &self,
        u: &DMatrix<f64>,
        y: &DMatrix<f64>,
        x0: &DVector<f64>,
    ) -> Result<OneStepPrediction> {
        self.check_io(u, Some(y), x0)?;
        let n = u.nrows();
        let mut yhat = DMatrix::zeros(n, self.ny());
        let mut x = x0.clone();
        for t in 0..n {
            let ut = u.row(t).transpose();
            let yh = &self.c * &x + &self.d * &ut;
            let e = y.row(t).transpose() - &yh;
            yhat.row_mut(t).copy_from(&yh.transpose());
            x = &self.a * &x + &self.b * &ut + &self.k * e;
        }
        let residuals = y - &yhat;
        Ok(OneStepPrediction { yhat, residuals })
    }

    /// k-step-ahead prediction (4.12): `yhat(t|t-k)` for every `t`. The
    /// one-step predictor runs over the data; from its state at `t-k+1`
    /// the model is simulated `k-1` steps with the measured inputs only.
    /// Samples with `t < k` use the predictor started at `x0` with the data
    /// available. `k = 1` is the one-step predictor.
    pub fn predict_k_step(
        &self,
        u: &DMatrix<f64>,
        y: &DMatrix<f64>,
        x0: &DVector<f64>,
        k: usize,
    ) -> Result<DMatrix<f64>> {
        if k == 0 {
            return Err(SysidError::invalid("prediction horizon k must be >= 1"));
        }
        self.check_io(u, Some(y), x0)?;
        let n = u.nrows();
        let nx = self.nx();
        // Predictor states xp[s] = x(s|s-1), s = 0..n.
        let mut xp = DMatrix::zeros(nx, n + 1);
        xp.column_mut(0).copy_from(x0);
        for t in 0..n {
            let x = xp.column(t).into_owned();
            let ut = u.row(t).transpose();
            let e = y.row(t).transpose() - &self.c * &x - &self.d * &ut;
            let xn = &self.a * &x + &self.b * &ut + &self.k * e;
            xp.column_mut(t + 1).copy_from(&xn);
        }
        let mut out = DMatrix::zeros(n, self.ny());
        for t in 0..n {
            let s = (t + 1).saturating_sub(k);
            let mut x = xp.column(s).into_owned();
            for j in s..t {
                x = &self.a * &x + &self.b * u.row(j).transpose();
            }
            let yt = &self.c * &x + &self.d * u.row(t).transpose();
            out.row_mut(t).copy_from(&yt.transpose());
        }
        Ok(out)
    }

    /// Frequency response `G(e^{jw})` at `w` radians per sample (`ny x nu`).
    pub fn frequency_response(&self, w: f64) -> Result<DMatrix<Complex<f64>>> {
        let z = Complex::new(w.cos(), w.sin());
        self.transfer_at(z, &self.b, &self.d)
    }

    /// Frequency response of the noise model `H(e^{jw}) = I + C (zI - A)^-1 K`.
    pub fn noise_response(&self, w: f64) -> Result<DMatrix<Complex<f64>>> {
        let z = Complex::new(w.cos(), w.sin());
        self.transfer_at(z, &self.k, &DMatrix::identity(self.ny(), self.ny()))
    }

    fn transfer_at(
        &self,
        z: Complex<f64>,
        b: &DMatrix<f64>,
        d: &DMatrix<f64>,
    ) -> Result<DMatrix<Complex<f64>>> {
        let nx = self.nx();
        let cplx = |m: &DMatrix<f64>| m.map(|v| Complex::new(v, 0.0));
        if nx == 0 {
            return Ok(cplx(d));
        }
        let mut m = -cplx(&self.a);
        for i in 0..nx {
            m[(i, i)] += z;
        }
        let x = m
            .lu()
            .solve(&cplx(b))
            .ok_or_else(|| SysidError::Numerical(format!("z = {z} is a pole of the model")))?;
        Ok(cplx(&self.c) * x + cplx(d))
    }

    /// Steady-state gain `G(1) = C (I - A)^-1 B + D`.
    pub fn dc_gain(&self) -> Result<DMatrix<f64>> {
        Ok(self.frequency_response(0.0)?.map(|c| c.re))
    }

    /// Applies a state transformation `x = T z`: `(T^-1 A T, T^-1 B, C T, D, T^-1 K)`.
    pub fn transform(&self, t: &DMatrix<f64>) -> Result<Self> {
        let ti = t
            .clone()
            .try_inverse()
            .ok_or_else(|| SysidError::Numerical("state transformation is singular".into()))?;
        Ok(InnovationModel {
            ts: self.ts,
            a: &ti * &self.a * t,
            b: &ti * &self.b,
            c: &self.c * t,
            d: self.d.clone(),
            k: &ti * &self.k,
        })
    }

    /// The model as a `kestrel.ss.v1` file, with the operating point
    /// (offsets removed before identification) and signal names.
    pub fn to_ss_model(
        &self,
        u0: Option<&DVector<f64>>,
        y0: Option<&DVector<f64>>,
        inputs: Option<&[String]>,
        outputs: Option<&[String]>,
    ) -> Result<SsModel> {
        let mut m = SsModel::new(
            self.ts,
            self.a.clone(),
            self.b.clone(),
            self.c.clone(),
            self.d.clone(),
        )
        .map_err(|e| SysidError::invalid(e.to_string()))?;
        m.k = Some(self.k.clone());
        m.u0 = u0.cloned();
        m.y0 = y0.cloned();
        m.inputs = inputs.map(|s| s.to_vec());
        m.outputs = outputs.map(|s| s.to_vec());
        m.validate()
            .map_err(|e| SysidError::invalid(e.to_string()))?;
        Ok(m)
    }

    /// Reads the model part of a `kestrel.ss.v1` file (a missing `K` is zero).
    pub fn from_ss_model(m: &SsModel) -> Result<Self> {
        let k =
            m.k.clone()
                .unwrap_or_else(|| DMatrix::zeros(m.nx(), m.ny()));
        InnovationModel::new(m.ts, m.a.clone(), m.b.clone(), m.c.clone(), m.d.clone(), k)
    }

    pub(crate) fn check_io(
        &self,
        u: &DMatrix<f64>,
        y: Option<&DMatrix<f64>>,
        x0: &DVector<f64>,
    ) -> Result<()> {
        if u.ncols() != self.nu() {
            return Err(SysidError::dim("input columns", self.nu(), u.ncols()));
        }
        if let Some(y) = y {
            if y.ncols() != self.ny() {
                return Err(SysidError::dim("output columns", self.ny(), y.ncols()));
            }
            if y.nrows() != u.nrows() {
                return Err(SysidError::dim("output samples", u.nrows(), y.nrows()));
            }
        }
        if x0.len() != self.nx() {
            return Err(SysidError::dim("initial state", self.nx(), x0.len()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn siso() -> InnovationModel {
        InnovationModel::new(
            1.0,
            DMatrix::from_row_slice(1, 1, &[0.5]),
            DMatrix::from_row_slice(1, 1, &[1.0]),
            DMatrix::from_row_slice(1, 1, &[2.0]),
            DMatrix::from_row_slice(1, 1, &[0.0]),
            DMatrix::from_row_slice(1, 1, &[0.3]),
        )
        .unwrap()
    }

    #[test]
    fn dc_gain_and_frequency_response_closed_form() {
        let m = siso();
        // G(z) = 2 / (z - 0.5); G(1) = 4.
        assert!((m.dc_gain().unwrap()[(0, 0)] - 4.0).abs() < 1e-14);
        let w: f64 = 0.7;
        let z = Complex::new(w.cos(), w.sin());
        let g = Complex::new(2.0, 0.0) / (z - 0.5);
        assert!((m.frequency_response(w).unwrap()[(0, 0)] - g).norm() < 1e-14);
    }

    #[test]
    fn k_step_prediction_limits() {
        let m = siso();
        let u = DMatrix::from_fn(50, 1, |i, _| ((i * 7) % 5) as f64 - 2.0);
        let y = DMatrix::from_fn(50, 1, |i, _| ((i * 3) % 7) as f64 - 3.0);
        let x0 = DVector::zeros(1);
        let p1 = m.predict_one_step(&u, &y, &x0).unwrap();
        let k1 = m.predict_k_step(&u, &y, &x0, 1).unwrap();
        assert!((&p1.yhat - &k1).norm() < 1e-12);
        // k larger than the data: pure simulation.
        let sim = m.simulate(&u, &x0).unwrap();
        let kbig = m.predict_k_step(&u, &y, &x0, 100).unwrap();
        assert!((&sim - &kbig).norm() < 1e-12);
    }

    #[test]
    fn bad_shapes_are_errors() {
        let e = InnovationModel::new(
            1.0,
            DMatrix::zeros(2, 2),
            DMatrix::zeros(3, 1),
            DMatrix::zeros(1, 2),
            DMatrix::zeros(1, 1),
            DMatrix::zeros(2, 1),
        );
        assert!(matches!(e, Err(SysidError::Dimension { .. })));
        let m = siso();
        assert!(
            m.simulate(&DMatrix::zeros(5, 2), &DVector::zeros(1))
                .is_err()
        );
    }
}
