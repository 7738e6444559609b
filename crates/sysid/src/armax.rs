//! MIMO ARMAX models by the Hannan-Rissanen two-stage least squares and
//! pseudo-linear regression: a baseline with a noise model and a start
//! structure for [`pem`](crate::pem()).

use crate::arx::{ArxSettings, arx, default_lags, solve_normal_equations};
use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::model::InnovationModel;
use nalgebra::DMatrix;

/// The structure of a MIMO ARMAX model
///
/// `y(t) = sum_(i=1..na) a_i y(t-i) + sum_(j=0..nb-1) b_j u(t-nk-j)
///        + e(t) + sum_(l=1..nc) c_l e(t-l)`
///
/// with full `ny x ny` matrices `a_i`, `c_l` and `ny x nu` matrices `b_j`
/// (MATLAB's `A(q) y = B(q) u + C(q) e` with `A = I - sum a_i q^-i`,
/// `C = I + sum c_l q^-l`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArmaxSettings {
    /// Output lags `na`.
    pub na: usize,
    /// Input lags `nb`.
    pub nb: usize,
    /// Noise lags `nc` (0: an ARX model).
    pub nc: usize,
    /// Input delay `nk` in samples.
    pub nk: usize,
    /// Lags of the high-order ARX model whose residuals stand in for the
    /// innovations in the first regression; `0` takes
    /// `max(10, 2 (na + nc))`, or on a record too short for that ARX the
    /// largest lag count from `max(na, nc) + 1` whose ARX has at least
    /// twice as many regression rows as parameters per output.
    /// [`ArmaxModel::settings`] holds the count used.
    pub arx_lags: usize,
    /// Pseudo-linear regression passes after the first (each recomputes
    /// the innovations with the current model and refits); the pass with
    /// the smallest residual covariance trace is kept.
    pub iterations: usize,
}

impl Default for ArmaxSettings {
    /// `na = nb = nc = 2`, `nk = 1`, automatic ARX lags, 5 passes.
    fn default() -> Self {
        ArmaxSettings {
            na: 2,
            nb: 2,
            nc: 2,
            nk: 1,
            arx_lags: 0,
            iterations: 5,
        }
    }
}

impl ArmaxSettings {
    /// The largest lag, `max(na, nk + nb - 1, nc, 1)`: the realisation
    /// has `ny` times that many states.
    pub fn max_lag(&self) -> usize {
        let input = if self.nb > 0 {
            self.nk + self.nb - 1
        } else {
            0
        };
        self.na.max(input).max(self.nc).max(1)
    }
}

/// A MIMO ARMAX model estimated by [`armax`], in the units of the data
/// (no constant term: remove the operating point first).
#[derive(Clone, Debug, PartialEq)]
pub struct ArmaxModel {
    /// Sample time in seconds.
    pub ts: f64,
    /// The structure.
    pub settings: ArmaxSettings,
    /// Number of inputs (also when `nb = 0`).
    pub nu: usize,
    /// `a_1 .. a_na` (`ny x ny`), `a[i]` multiplies `y(t-1-i)`.
    pub a: Vec<DMatrix<f64>>,
    /// `b_0 .. b_(nb-1)` (`ny x nu`), `b[j]` multiplies `u(t-nk-j)`.
    pub b: Vec<DMatrix<f64>>,
    /// `c_1 .. c_nc` (`ny x ny`), `c[l]` multiplies `e(t-1-l)`.
    pub c: Vec<DMatrix<f64>>,
    /// Covariance of the innovations on the estimation data (`ny x ny`).
    pub noise_covariance: DMatrix<f64>,
    /// Trace of that covariance after every pass (the first is the
    /// Hannan-Rissanen regression).
    pub history: Vec<f64>,
}

impl ArmaxModel {
    /// The model as an innovation form of order `ny max_lag` with the same
    /// predictions (observer canonical form, as
    /// [`ArxModel::to_innovation_model`](crate::ArxModel::to_innovation_model)):
    /// `A` block companion of `a_i`, `B_j = b_j + a_j b_0` (lag `j`),
    /// `C = [I 0 ..]`, `D = b_0` (lag 0), `K_j = a_j + c_j`. The
    /// predictor `A - K C` is the block companion matrix of `-c_j`, stable
    /// exactly when `C(q)` has its zeros inside the unit circle. Predict
    /// and validate through it ([`predict_fit`](crate::predict_fit),
    /// [`compare`](crate::compare)) or start [`pem`](crate::pem()) from it.
    pub fn to_innovation_model(&self) -> Result<InnovationModel> {
        let ny = self.noise_covariance.nrows();
        let nu = self.nu;
        let s = self.settings;
        let n = s.max_lag();
        let nx = ny * n;
        let lag = |v: &[DMatrix<f64>], i: usize, r: usize, c: usize| {
            i.checked_sub(1)
                .and_then(|k| v.get(k).cloned())
                .unwrap_or_else(|| DMatrix::zeros(r, c))
        };
        let b_at = |l: usize| {
            l.checked_sub(s.nk)
                .and_then(|j| self.b.get(j).cloned())
                .unwrap_or_else(|| DMatrix::zeros(ny, nu))
        };
        let b0 = b_at(0);
        let mut a = DMatrix::zeros(nx, nx);
        let mut b = DMatrix::zeros(nx, nu);
        let mut k = DMatrix::zeros(nx, ny);
        for j in 1..=n {
            let aj = lag(&self.a, j, ny, ny);
            let cj = lag(&self.c, j, ny, ny);
            let r = (j - 1) * ny;
            a.view_mut((r, 0), (ny, ny)).copy_from(&aj);
            if j < n {
                a.view_mut((r, j * ny), (ny, ny))
                    .copy_from(&DMatrix::identity(ny, ny));
            }
            b.view_mut((r, 0), (ny, nu))
                .copy_from(&(b_at(j) + &aj * &b0));
            k.view_mut((r, 0), (ny, ny)).copy_from(&(aj + cj));
        }
        let mut c = DMatrix::zeros(ny, nx);
        c.view_mut((0, 0), (ny, ny))
            .copy_from(&DMatrix::identity(ny, ny));
        InnovationModel::new(self.ts, a, b, c, b0, k)
    }
}

/// MIMO ARMAX by the Hannan-Rissanen method: a high-order ARX model
/// ([`arx`](crate::arx())) gives residuals `e0(t)` that stand in for
/// the innovations; the least squares of `y(t)` on its past, the inputs
/// and `e0(t-1) .. e0(t-nc)` gives `a`, `b`, `c`; then pseudo-linear
/// regression passes recompute the innovations with the current model
/// (`e = y - yhat`, recursively) and refit, keeping the pass whose
/// residuals are smallest. Consistent for open-loop data; on closed-loop
/// data as consistent as the high-order ARX step (the regressors are
/// past values only). Every experiment is one block; the first
/// `max_lag` samples of each enter only as history.
///
/// Errors: a structure without parameters, a constant signal, too few
/// samples, linearly dependent regressors (as [`arx`](crate::arx())).
///
/// ```
/// use kestrel_sysid::{armax, persistence_fit, predict_fit, synthetic, ArmaxSettings};
/// let truth = synthetic::random_model(2, 1, 1, 4, 0.8);
/// let data = synthetic::simulate(&truth, 3000, 0.3, 2).unwrap();
/// let m = armax(&data, &ArmaxSettings::default()).unwrap();
/// let ss = m.to_innovation_model().unwrap();
/// assert_eq!(ss.nx(), 2);
/// assert!(ss.radius_predictor() < 1.0);
/// let fit = predict_fit(&ss, &data, 1).unwrap()[0];
/// assert!(fit > persistence_fit(&data, Some(1))[0]);
/// ```
pub fn armax(data: &IoData, settings: &ArmaxSettings) -> Result<ArmaxModel> {
    let s = *settings;
    if s.na == 0 && s.nb == 0 && s.nc == 0 {
        return Err(SysidError::invalid("an ARMAX model needs na, nb or nc > 0"));
    }
    let (nu, ny) = (data.nu(), data.ny());
    let lag = s.max_lag();
    let np = ny * s.na + nu * s.nb + ny * s.nc;
    let rows = data.rows_after(lag);
    if rows < np + 1 {
        return Err(SysidError::TooFewSamples {
            what: format!("ARMAX with {np} parameters per output and {lag} lags"),
            needed: np + 1 + lag,
            found: data.n_samples(),
        });
    }
    let hl = if s.arx_lags == 0 {
        default_lags(
            data,
            10.max(2 * (s.na + s.nc)),
            s.na.max(s.nc) + 1,
            ArxSettings::lags,
        )
    } else {
        s.arx_lags
    };
    let s = ArmaxSettings { arx_lags: hl, ..s };
    let high = arx(data, &ArxSettings::lags(hl))?;
    let first = high.first_predicted(1);
    let mut innov: Vec<DMatrix<f64>> = high
        .predict(data, 1)?
        .into_iter()
        .zip(data.experiments())
        .map(|(p, e)| {
            let mut r = &e.y - p;
            r.rows_mut(0, first.min(e.len())).fill(0.0);
            r
        })
        .collect();
    let mut best: Option<ArmaxModel> = None;
    let mut history = Vec::new();
    for pass in 0..=s.iterations {
        let model = match regress(data, &s, &innov, np, rows) {
            Ok(m) => m,
            // A later pass whose innovations degenerated (a diverging
            // predictor) ends the passes; the first one's error is the
            // data's.
            Err(e) if pass == 0 => return Err(e),
            Err(_) => break,
        };
        let tr = model.noise_covariance.trace();
        history.push(tr);
        if !tr.is_finite() {
            break;
        }
        innov = innovations(data, &model);
        if best
            .as_ref()
            .is_none_or(|b| tr < b.noise_covariance.trace())
        {
            best = Some(model);
        }
    }
    let mut best = best.ok_or_else(|| SysidError::Numerical("ARMAX regression failed".into()))?;
    best.history = history;
    Ok(best)
}

/// The least squares of `y(t)` on `[y lags, u lags, e lags]` with the
/// given innovations.
fn regress(
    data: &IoData,
    s: &ArmaxSettings,
    innov: &[DMatrix<f64>],
    np: usize,
    rows: usize,
) -> Result<ArmaxModel> {
    let (nu, ny) = (data.nu(), data.ny());
    let lag = s.max_lag();
    let mut phi = DMatrix::zeros(rows, np);
    let mut yt = DMatrix::zeros(rows, ny);
    let mut r = 0;
    for (e, en) in data.experiments().iter().zip(innov) {
        for t in lag..e.len() {
            let mut c = 0;
            for i in 1..=s.na {
                phi.view_mut((r, c), (1, ny)).copy_from(&e.y.row(t - i));
                c += ny;
            }
            for j in 0..s.nb {
                phi.view_mut((r, c), (1, nu))
                    .copy_from(&e.u.row(t - s.nk - j));
                c += nu;
            }
            for l in 1..=s.nc {
                phi.view_mut((r, c), (1, ny)).copy_from(&en.row(t - l));
                c += ny;
            }
            yt.row_mut(r).copy_from(&e.y.row(t));
            r += 1;
        }
    }
    let theta = solve_normal_equations(&phi.tr_mul(&phi), &phi.tr_mul(&yt))?;
    let res = &yt - &phi * &theta;
    let lambda = res.tr_mul(&res) / rows as f64;
    let block = |c0: usize, w: usize| theta.rows(c0, w).transpose();
    let mut c = 0;
    let mut take = |count: usize, w: usize| {
        let v: Vec<DMatrix<f64>> = (0..count).map(|k| block(c + k * w, w)).collect();
        c += count * w;
        v
    };
    let a = take(s.na, ny);
    let b = take(s.nb, nu);
    let cm = take(s.nc, ny);
    Ok(ArmaxModel {
        ts: data.ts(),
        settings: *s,
        nu,
        a,
        b,
        c: cm,
        noise_covariance: lambda,
        history: Vec::new(),
    })
}

/// The innovations `e(t) = y(t) - yhat(t)` of the model, recursively
/// (zero for the first `max_lag` samples of every experiment).
fn innovations(data: &IoData, m: &ArmaxModel) -> Vec<DMatrix<f64>> {
    let s = m.settings;
    let lag = s.max_lag();
    data.experiments()
        .iter()
        .map(|e| {
            let ny = e.y.ncols();
            let mut en = DMatrix::zeros(e.len(), ny);
            for t in lag..e.len() {
                let mut v = e.y.row(t).transpose();
                for (i, ai) in m.a.iter().enumerate() {
                    v -= ai * e.y.row(t - 1 - i).transpose();
                }
                for (j, bj) in m.b.iter().enumerate() {
                    v -= bj * e.u.row(t - s.nk - j).transpose();
                }
                for (l, cl) in m.c.iter().enumerate() {
                    v -= cl * en.row(t - 1 - l).transpose();
                }
                if v.iter().any(|x| !x.is_finite() || x.abs() > 1e150) {
                    // A predictor that diverges (C(q) not minimum phase):
                    // leave the rest zero; the pass's fit will show it.
                    break;
                }
                en.row_mut(t).copy_from(&v.transpose());
            }
            en
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::Rng;
    use crate::validate::predict_fit;

    /// `y = 0.7 y(t-1) + u(t-1) + 0.5 u(t-2) + e + 0.6 e(t-1)`, one input
    /// and one output.
    fn siso(n: usize, seed: u64) -> IoData {
        let mut rng = Rng::new(seed);
        let u = rng.normal_matrix(n, 1);
        let e = rng.normal_matrix(n, 1) * 0.5;
        let mut y = DMatrix::zeros(n, 1);
        for t in 2..n {
            y[(t, 0)] = 0.7 * y[(t - 1, 0)]
                + u[(t - 1, 0)]
                + 0.5 * u[(t - 2, 0)]
                + e[(t, 0)]
                + 0.6 * e[(t - 1, 0)];
        }
        IoData::new(1.0, u, y).unwrap()
    }

    #[test]
    fn recovers_a_known_armax_model_and_beats_arx_of_the_same_lags() {
        let data = siso(20_000, 3);
        let s = ArmaxSettings {
            na: 1,
            nb: 2,
            nc: 1,
            ..Default::default()
        };
        let m = armax(&data, &s).unwrap();
        let got = [
            m.a[0][(0, 0)],
            m.b[0][(0, 0)],
            m.b[1][(0, 0)],
            m.c[0][(0, 0)],
        ];
        for (g, w) in got.iter().zip([0.7, 1.0, 0.5, 0.6]) {
            assert!((g - w).abs() < 0.03, "{got:?}");
        }
        assert!((m.noise_covariance[(0, 0)] - 0.25).abs() < 0.01);
        // The passes do not make the fit worse than the first.
        assert!(
            m.history
                .iter()
                .all(|h| *h >= m.noise_covariance.trace() - 1e-12)
        );
        // Its one-step predictions match the optimal predictor's and beat
        // an ARX model with the same output and input lags.
        let ss = m.to_innovation_model().unwrap();
        let f_armax = predict_fit(&ss, &data, 1).unwrap()[0];
        let a = crate::arx::arx(
            &data,
            &ArxSettings {
                na: 1,
                nb: 2,
                nk: 1,
            },
        )
        .unwrap();
        let f_arx = a.predict_fit(&data, 1).unwrap()[0];
        assert!(f_armax > f_arx + 1.0, "{f_armax} vs {f_arx}");
    }

    #[test]
    fn realisation_predicts_as_the_recursion() {
        let data = siso(500, 5);
        let m = armax(&data, &ArmaxSettings::default()).unwrap();
        let ss = m.to_innovation_model().unwrap();
        // Innovations of the recursion = residuals of the realisation's
        // predictor started from the state the recursion implies (zero
        // innovations before max_lag): compare after a burn-in.
        let e = &data.experiments()[0];
        let x0 = nalgebra::DVector::zeros(ss.nx());
        let r = ss.predict_one_step(&e.u, &e.y, &x0).unwrap().residuals;
        let en = &innovations(&data, &m)[0];
        let tail = e.len() - 200;
        assert!((r.rows(200, tail) - en.rows(200, tail)).amax() < 1e-8);
    }

    #[test]
    fn a_short_record_shrinks_the_long_arx() {
        // 28 samples: the long ARX of 10 lags (20 parameters) has only 18
        // rows. The largest with twice as many rows as parameters is 5
        // (23 rows, 10 parameters; 6 has 22 rows for 12).
        let data = siso(28, 3);
        let m = armax(&data, &ArmaxSettings::default()).unwrap();
        assert_eq!(m.settings.arx_lags, 5);
        let at = |l: usize| {
            armax(
                &data,
                &ArmaxSettings {
                    arx_lags: l,
                    ..Default::default()
                },
            )
        };
        assert!(matches!(at(10), Err(SysidError::TooFewSamples { .. })));
        assert_eq!(at(5).unwrap(), m);
        // A long record keeps max(10, 2 (na + nc)).
        let m = armax(&siso(500, 3), &ArmaxSettings::default()).unwrap();
        assert_eq!(m.settings.arx_lags, 10);
    }

    #[test]
    fn bad_input_is_an_error() {
        // 8 samples: 6 rows for the 6 ARMAX(2, 2, 2) parameters; the
        // error names the ARMAX, not its long ARX step.
        match armax(&siso(8, 1), &ArmaxSettings::default()) {
            Err(SysidError::TooFewSamples { what, .. }) => {
                assert!(what.contains("ARMAX"), "{what}")
            }
            other => panic!("{other:?}"),
        }
        let none = ArmaxSettings {
            na: 0,
            nb: 0,
            nc: 0,
            ..Default::default()
        };
        assert!(armax(&siso(300, 1), &none).is_err());
        // An ARMA model (nb = 0) still takes the data's inputs.
        let arma = ArmaxSettings {
            nb: 0,
            ..Default::default()
        };
        let m = armax(&siso(300, 1), &arma).unwrap();
        assert_eq!(m.to_innovation_model().unwrap().nu(), 1);
        let e = siso(300, 2).experiments()[0].clone();
        let flat = IoData::new(1.0, DMatrix::zeros(300, 1), e.y).unwrap();
        assert!(matches!(
            armax(&flat, &ArmaxSettings::default()),
            Err(SysidError::ConstantInput { .. })
        ));
    }
}
