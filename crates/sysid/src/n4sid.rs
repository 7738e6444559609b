//! Subspace identification (N4SID family) with MOESP or CVA weighting.

use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::{self, inv_sqrt_spd, lstsq, pinv, r_factor, spectral_radius};
use crate::model::InnovationModel;
use crate::validate::estimate_x0_simulation;
use nalgebra::{DMatrix, DVector};

/// The weighting of the oblique projection before the SVD.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Weighting {
    /// MOESP: `W1 = I`, `W2` the projection onto the orthogonal complement
    /// of the future inputs (the SVD of `L32` of the LQ factor).
    #[default]
    Moesp,
    /// Canonical variate analysis: as MOESP with `W1` the inverse square
    /// root of the covariance of the future outputs with the future inputs
    /// projected out; singular values are canonical correlations.
    Cva,
    /// Unweighted N4SID (`W1 = I`, `W2 = I`).
    Unweighted,
}

/// How [`n4sid`] estimates the system matrices once the SVD has given the
/// extended observability matrix `Gamma`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MatrixEstimate {
    /// `A`, `C` from the shift invariance of `Gamma`; `B`, `D` and the
    /// initial states by output-error least squares with `A`, `C` fixed
    /// (the simulation error is linear in them); `K` from the residuals of
    /// the state sequence with these matrices.
    #[default]
    OutputError,
    /// `A`, `B`, `C`, `D` together by least squares on the state sequence
    /// `Gamma^+ O_i` and its shift (Van Overschee and De Moor's
    /// algorithm 2, as SIPPY and nfoursid do), and `K` from the residual
    /// covariances of that same regression (a Riccati equation): one
    /// consistent fit of the one-step predictor rather than of the
    /// simulation. The initial states are then least squares with the
    /// matrices fixed.
    StateRegression,
}

/// Settings of [`n4sid`].
#[derive(Clone, Debug, PartialEq)]
pub struct N4sidSettings {
    /// Model order; `None` takes the suggested order.
    pub order: Option<usize>,
    /// Largest order considered when suggesting one.
    pub max_order: usize,
    /// Number of block rows `i` of the future (and of the past unless
    /// [`past_horizon`](Self::past_horizon) is set); `None` chooses
    /// `max(10, ceil((n_max + 1) / ny) + 1)`.
    pub horizon: Option<usize>,
    /// Number of block rows `p` of the past when it differs from the
    /// future's; `None` takes the future horizon. A past longer than the
    /// future brings the state estimates closer to a stationary Kalman
    /// filter's (Jansson; Chiuso); on the DaISy steam generator it did
    /// not improve the model.
    pub past_horizon: Option<usize>,
    /// The weighting.
    pub weighting: Weighting,
    /// Estimate a feed-through `D` (otherwise `D = 0`).
    pub feedthrough: bool,
    /// Estimate the innovation gain `K` (otherwise `K = 0`).
    pub estimate_k: bool,
    /// How the system matrices follow from `Gamma`.
    pub matrices: MatrixEstimate,
}

impl Default for N4sidSettings {
    fn default() -> Self {
        N4sidSettings {
            order: None,
            max_order: 10,
            horizon: None,
            past_horizon: None,
            weighting: Weighting::default(),
            feedthrough: false,
            estimate_k: true,
            matrices: MatrixEstimate::default(),
        }
    }
}

/// Result of [`n4sid`].
#[derive(Clone, Debug, PartialEq)]
pub struct N4sidResult {
    /// The estimated model (in the units of the data).
    pub model: InnovationModel,
    /// Estimated initial state of every experiment.
    pub x0: Vec<DVector<f64>>,
    /// The singular values of the weighted oblique projection.
    pub singular_values: Vec<f64>,
    /// The order suggested by the largest gap of the singular values.
    pub suggested_order: usize,
    /// The order used.
    pub order: usize,
    /// The horizon `i` used.
    pub horizon: usize,
}

/// Input and output scaling used internally (each signal to unit variance).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Scaling {
    pub su: DVector<f64>,
    pub sy: DVector<f64>,
}

impl Scaling {
    pub fn of(data: &IoData) -> Result<Self> {
        let (su, sy) = data.check_excitation()?;
        Ok(Scaling {
            su: su.map(|s| 1.0 / s),
            sy: sy.map(|s| 1.0 / s),
        })
    }
    /// Model of the scaled data -> model of the original data.
    pub fn unscale(&self, m: &InnovationModel) -> InnovationModel {
        let su = DMatrix::from_diagonal(&self.su);
        let sy = DMatrix::from_diagonal(&self.sy);
        let syi = DMatrix::from_diagonal(&self.sy.map(|s| 1.0 / s));
        InnovationModel {
            ts: m.ts,
            a: m.a.clone(),
            b: &m.b * &su,
            c: &syi * &m.c,
            d: &syi * &m.d * &su,
            k: &m.k * &sy,
        }
    }
    /// Model of the original data -> model of the scaled data.
    pub fn scale(&self, m: &InnovationModel) -> InnovationModel {
        let inv = Scaling {
            su: self.su.map(|s| 1.0 / s),
            sy: self.sy.map(|s| 1.0 / s),
        };
        inv.unscale(m)
    }
}

/// Suggests an order from singular values: the largest drop of
/// `log10(s_n / s_{n+1})` over `n = 1..=max_order`.
pub fn suggest_order(sv: &[f64], max_order: usize) -> usize {
    let mut best = (1, f64::NEG_INFINITY);
    for n in 1..=max_order.min(sv.len().saturating_sub(1)) {
        let gap = (sv[n - 1].max(1e-300) / sv[n].max(1e-300)).log10();
        if gap > best.1 {
            best = (n, gap);
        }
    }
    best.0
}

/// Subspace identification of an innovation-form model
/// `x+ = A x + B u + K e`, `y = C x + D u + e`.
///
/// Steps (Van Overschee and De Moor; Verhaegen's MOESP; Larimore's CVA):
/// every signal is scaled to unit variance; block Hankel matrices of `p`
/// past and `i` future block rows (`p = i` unless
/// [`N4sidSettings::past_horizon`] is set) are built per experiment and
/// placed side by side (experiments are never joined); an LQ
/// factorisation gives the oblique projection of the future outputs onto
/// the past along the future inputs; its weighted SVD gives the extended
/// observability matrix `Gamma`. With [`MatrixEstimate::OutputError`] (the
/// default) `C` (first block row) and `A` (shift invariance, with a
/// stabilising fallback) follow from `Gamma`, and `B`, `D` and the initial
/// states solve a linear least-squares output-error problem with `A`, `C`
/// fixed; with [`MatrixEstimate::StateRegression`] all four come from a
/// least-squares regression on the state sequence `Gamma^+ O_i` and its
/// shift. `K` is the stationary Kalman gain of the covariances of the
/// state and output residuals of that sequence under the chosen
/// matrices (shrunk if `A - K C` would be unstable).
///
/// ```
/// use kestrel_sysid::{n4sid, synthetic, N4sidSettings};
/// let truth = synthetic::random_model(3, 2, 2, 1, 0.9);
/// let data = synthetic::simulate(&truth, 2000, 0.05, 7).unwrap();
/// let r = n4sid(&data, &N4sidSettings { order: Some(3), ..Default::default() }).unwrap();
/// assert_eq!(r.model.nx(), 3);
/// assert!(r.model.radius_a() < 1.0);
/// ```
pub fn n4sid(data: &IoData, settings: &N4sidSettings) -> Result<N4sidResult> {
    let scaling = Scaling::of(data)?;
    let sdata = data.scaled(&scaling.su, &scaling.sy);
    let (nu, ny) = (data.nu(), data.ny());
    let n_req = settings.order.unwrap_or(0);
    let nmax = settings.max_order.max(n_req).max(1);
    let i = match settings.horizon {
        Some(i) => i,
        None => 10usize.max((nmax + 1).div_ceil(ny) + 1),
    };
    if i * ny <= nmax || i < 2 {
        return Err(SysidError::invalid(format!(
            "horizon {i} too short for order {nmax} with {ny} outputs (need i * ny > order)"
        )));
    }
    let p = settings.past_horizon.unwrap_or(i);
    if p == 0 {
        return Err(SysidError::invalid("past horizon must be >= 1"));
    }
    if settings.order == Some(0) {
        return Err(SysidError::invalid("model order must be >= 1"));
    }
    let rows = (i + p) * (nu + ny);
    let cols: usize = sdata
        .experiments()
        .iter()
        .map(|e| (e.len() + 1).saturating_sub(i + p))
        .sum();
    if cols < rows {
        let needed = rows + i + p - 1;
        return Err(SysidError::TooFewSamples {
            what: format!("N4SID of order {nmax} with horizons {i}/{p} ({rows} Hankel rows)"),
            needed,
            found: data.n_samples(),
        });
    }
    // Ht: one row per Hankel column, columns ordered [Uf, Up, Yp, Yf].
    let (m1, m2, m3) = (i * nu, p * (nu + ny), i * ny);
    let mut ht = DMatrix::<f64>::zeros(cols, rows);
    let mut col0 = 0;
    let mut spans = Vec::new();
    for e in sdata.experiments() {
        let j = (e.len() + 1).saturating_sub(i + p);
        for c in 0..j {
            let r = col0 + c;
            for b in 0..i {
                for q in 0..nu {
                    ht[(r, b * nu + q)] = e.u[(c + p + b, q)];
                }
                for q in 0..ny {
                    ht[(r, m1 + m2 + b * ny + q)] = e.y[(c + p + b, q)];
                }
            }
            for b in 0..p {
                for q in 0..nu {
                    ht[(r, m1 + b * nu + q)] = e.u[(c + b, q)];
                }
                for q in 0..ny {
                    ht[(r, m1 + p * nu + b * ny + q)] = e.y[(c + b, q)];
                }
            }
        }
        spans.push((col0, j));
        col0 += j;
    }
    let wp_t = ht.columns(m1, m2).into_owned(); // J x m2
    let l = r_factor(ht).transpose();
    let l22 = l.view((m1, m1), (m2, m2)).into_owned();
    let l32 = l.view((m1 + m2, m1), (m3, m2)).into_owned();
    let l33 = l.view((m1 + m2, m1 + m2), (m3, m3)).into_owned();
    let l21 = l.view((m1, 0), (m2, m1)).into_owned();
    let lwp = &l32 * pinv(&l22);
    let (w1inv, target) = match settings.weighting {
        Weighting::Moesp => (None, l32.clone()),
        Weighting::Cva => {
            let mut cov = &l32 * l32.transpose() + &l33 * l33.transpose();
            // A small ridge keeps the weight defined for noise-free data.
            let ridge = 1e-8 * cov.trace() / m3 as f64;
            for d in 0..m3 {
                cov[(d, d)] += ridge;
            }
            let w = inv_sqrt_spd(&cov)?;
            let winv = w
                .clone()
                .try_inverse()
                .ok_or_else(|| SysidError::Numerical("CVA weight not invertible".into()))?;
            let t = &w * &l32;
            (Some(winv), t)
        }
        Weighting::Unweighted => {
            let mut lw = DMatrix::zeros(m2, m1 + m2);
            lw.view_mut((0, 0), (m2, m1)).copy_from(&l21);
            lw.view_mut((0, m1), (m2, m2)).copy_from(&l22);
            (None, &lwp * lw)
        }
    };
    let svd = target.svd(true, false);
    let u = svd
        .u
        .ok_or_else(|| SysidError::Numerical("SVD failed".into()))?;
    // Sort singular values descending (nalgebra does not guarantee order).
    let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
    idx.sort_by(|a, b| svd.singular_values[*b].total_cmp(&svd.singular_values[*a]));
    let sv: Vec<f64> = idx.iter().map(|&k| svd.singular_values[k]).collect();
    let suggested = suggest_order(&sv, nmax.min(m3 - ny));
    let n = settings.order.unwrap_or(suggested);
    if n > m3 - ny {
        return Err(SysidError::invalid(format!(
            "order {n} too large for horizon {i} with {ny} outputs"
        )));
    }
    let mut gamma = DMatrix::zeros(m3, n);
    for (c, &k) in idx.iter().take(n).enumerate() {
        gamma.column_mut(c).copy_from(&(u.column(k) * sv[c].sqrt()));
    }
    if let Some(winv) = &w1inv {
        gamma = winv * gamma;
    }
    let c_gamma = gamma.rows(0, ny).into_owned();
    let g_up = gamma.rows(0, m3 - ny).into_owned();
    let g_dn = gamma.rows(ny, m3 - ny).into_owned();
    let mut a_gamma = lstsq(&g_up, &g_dn);
    if spectral_radius(&a_gamma) >= 1.0 {
        // Maciejowski's stabilising estimate: shift with a zero block appended.
        let mut g_dn0 = DMatrix::zeros(m3, n);
        g_dn0.rows_mut(0, m3 - ny).copy_from(&g_dn);
        a_gamma = lstsq(&gamma, &g_dn0);
    }
    // The state sequence (one column per Hankel column) and, per
    // experiment, its consecutive pairs with the input and output between.
    let states =
        || StateSequence::new(&(pinv(&gamma) * &lwp * wp_t.transpose()), &spans, &sdata, p);
    let (a, b, c_mat, d, x0s, seq) = match settings.matrices {
        MatrixEstimate::OutputError => {
            // B, D, x0 by output-error least squares with A, C fixed.
            let BdX0 { b, d, x0 } = fit_bd_x0(&a_gamma, &c_gamma, &sdata, settings.feedthrough)?;
            let seq = settings.estimate_k.then(states);
            (a_gamma, b, c_gamma, d, x0, seq)
        }
        MatrixEstimate::StateRegression => {
            let seq = states();
            let Abcd { a, b, c, d } = seq.regress(&a_gamma, settings.feedthrough);
            let trial = InnovationModel::new(
                data.ts(),
                a.clone(),
                b.clone(),
                c.clone(),
                d.clone(),
                DMatrix::zeros(n, ny),
            )?;
            let x0 = sdata
                .experiments()
                .iter()
                .map(|e| estimate_x0_simulation(&trial, &e.u, &e.y))
                .collect::<Result<Vec<_>>>()?;
            (a, b, c, d, x0, settings.estimate_k.then_some(seq))
        }
    };
    let k = match seq {
        Some(seq) => {
            let (q, s, r) = seq.residual_covariances(&a, &b, &c_mat, &d);
            let kk = match linalg::kalman_gain(&a, &c_mat, &q, &s, &r) {
                Ok(k) => k,
                Err(_) => &s * pinv(&r),
            };
            stabilise_k(&a, &c_mat, kk)
        }
        None => DMatrix::zeros(n, ny),
    };
    let scaled = InnovationModel::new(data.ts(), a, b, c_mat, d, k)?;
    let model = scaling.unscale(&scaled);
    Ok(N4sidResult {
        model,
        x0: x0s,
        singular_values: sv,
        suggested_order: suggested,
        order: n,
        horizon: i,
    })
}

/// Consecutive pairs of the estimated state sequence of [`n4sid`] with
/// the input and output at the first of each pair: column `t` of `x`,
/// `xn`, `u`, `y` holds `x_t`, `x_{t+1}`, `u_t`, `y_t`.
struct StateSequence {
    x: DMatrix<f64>,
    xn: DMatrix<f64>,
    u: DMatrix<f64>,
    y: DMatrix<f64>,
}

/// System matrices of a state-sequence regression.
struct Abcd {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
}

impl StateSequence {
    /// The pairs of `xs`, whose column `c0 + c` is the state at sample
    /// `c + past` of the experiment of `data` whose columns `spans`
    /// start at `c0`.
    fn new(xs: &DMatrix<f64>, spans: &[(usize, usize)], data: &IoData, past: usize) -> Self {
        let mut cols: [Vec<DVector<f64>>; 4] = Default::default();
        for (e, &(c0, j)) in data.experiments().iter().zip(spans) {
            for c in 0..j.saturating_sub(1) {
                cols[0].push(xs.column(c0 + c).into_owned());
                cols[1].push(xs.column(c0 + c + 1).into_owned());
                cols[2].push(e.u.row(c + past).transpose());
                cols[3].push(e.y.row(c + past).transpose());
            }
        }
        let [x, xn, u, y] = cols.map(|c| DMatrix::from_columns(&c));
        StateSequence { x, xn, u, y }
    }

    /// `[x+; y] = [A B; C D] [x; u]` by least squares (`D = 0` without
    /// feed-through). An unstable `A` is replaced by `a_stable` with `B`
    /// refitted for it.
    fn regress(&self, a_stable: &DMatrix<f64>, feedthrough: bool) -> Abcd {
        let StateSequence { x, xn, u, y } = self;
        let (n, nu, ny) = (x.nrows(), u.nrows(), y.nrows());
        let mut xu = x.clone().resize_vertically(n + nu, 0.0);
        xu.rows_mut(n, nu).copy_from(u);
        let ab = lstsq(&xu.transpose(), &xn.transpose()).transpose();
        let (mut a, mut b) = (
            ab.columns(0, n).into_owned(),
            ab.columns(n, nu).into_owned(),
        );
        if spectral_radius(&a) >= 1.0 {
            a = a_stable.clone();
            b = lstsq(&u.transpose(), &(xn - &a * x).transpose()).transpose();
        }
        let (c, d) = if feedthrough {
            let cd = lstsq(&xu.transpose(), &y.transpose()).transpose();
            (
                cd.columns(0, n).into_owned(),
                cd.columns(n, nu).into_owned(),
            )
        } else {
            (
                lstsq(&x.transpose(), &y.transpose()).transpose(),
                DMatrix::zeros(ny, nu),
            )
        };
        Abcd { a, b, c, d }
    }

    /// The covariances `Q`, `S`, `R` of the state and output residuals
    /// of the sequence under the given matrices.
    fn residual_covariances(
        &self,
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        c: &DMatrix<f64>,
        d: &DMatrix<f64>,
    ) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
        let w = &self.xn - a * &self.x - b * &self.u;
        let v = &self.y - c * &self.x - d * &self.u;
        let nn = v.ncols().max(1) as f64;
        (
            &w * w.transpose() / nn,
            &w * v.transpose() / nn,
            &v * v.transpose() / nn,
        )
    }
}

/// Shrinks `K` until `A - K C` is stable (spectral radius below 0.999).
pub(crate) fn stabilise_k(a: &DMatrix<f64>, c: &DMatrix<f64>, mut k: DMatrix<f64>) -> DMatrix<f64> {
    for _ in 0..60 {
        if linalg::spectral_radius(&(a - &k * c)) < 0.999 {
            return k;
        }
        k *= 0.85;
    }
    DMatrix::zeros(k.nrows(), k.ncols())
}

/// `B`, `D` and the initial states from [`fit_bd_x0`].
pub(crate) struct BdX0 {
    pub b: DMatrix<f64>,
    pub d: DMatrix<f64>,
    pub x0: Vec<DVector<f64>>,
}

/// Least squares for `B`, `D` (optional) and one initial state per
/// experiment, with `A`, `C` fixed: the output is linear in them.
pub(crate) fn fit_bd_x0(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    data: &IoData,
    feedthrough: bool,
) -> Result<BdX0> {
    let n = a.nrows();
    let (nu, ny) = (data.nu(), data.ny());
    let ne = data.experiments().len();
    let nb = n * nu;
    let nd = if feedthrough { ny * nu } else { 0 };
    let np = nb + nd + n * ne;
    let nrows = data.n_samples() * ny;
    let mut phi = DMatrix::<f64>::zeros(nrows, np);
    let mut rhs = DVector::<f64>::zeros(nrows);
    let mut row = 0;
    for (ei, e) in data.experiments().iter().enumerate() {
        // Z_q[k] = sum_{j<k} A^{k-1-j} u_q[j]  (n x n, column p <-> b_{p,q}).
        let mut z: Vec<DMatrix<f64>> = vec![DMatrix::zeros(n, n); nu];
        let mut ak = DMatrix::<f64>::identity(n, n); // A^k
        for t in 0..e.len() {
            for q in 0..nu {
                let cz = c * &z[q]; // ny x n
                for o in 0..ny {
                    for p in 0..n {
                        phi[(row + o, q * n + p)] = cz[(o, p)];
                    }
                }
            }
            if feedthrough {
                for o in 0..ny {
                    for q in 0..nu {
                        phi[(row + o, nb + q * ny + o)] = e.u[(t, q)];
                    }
                }
            }
            let cak = c * &ak;
            for o in 0..ny {
                for p in 0..n {
                    phi[(row + o, nb + nd + ei * n + p)] = cak[(o, p)];
                }
                rhs[row + o] = e.y[(t, o)];
            }
            for q in 0..nu {
                let mut zn = a * &z[q];
                for p in 0..n {
                    zn[(p, p)] += e.u[(t, q)];
                }
                z[q] = zn;
            }
            ak = a * ak;
            row += ny;
        }
    }
    let theta = lstsq(&phi, &DMatrix::from_column_slice(nrows, 1, rhs.as_slice()));
    let mut b = DMatrix::zeros(n, nu);
    for q in 0..nu {
        for p in 0..n {
            b[(p, q)] = theta[(q * n + p, 0)];
        }
    }
    let mut d = DMatrix::zeros(ny, nu);
    if feedthrough {
        for q in 0..nu {
            for o in 0..ny {
                d[(o, q)] = theta[(nb + q * ny + o, 0)];
            }
        }
    }
    let x0 = (0..ne)
        .map(|ei| DVector::from_fn(n, |p, _| theta[(nb + nd + ei * n + p, 0)]))
        .collect();
    Ok(BdX0 { b, d, x0 })
}

/// N4SID of the given `order` with the default settings, unwrapped: the
/// start the tests of this crate (N4SID, PEM, the workflow) compare with.
#[cfg(test)]
pub(crate) fn n4sid_of_order(data: &IoData, order: usize) -> N4sidResult {
    n4sid(
        data,
        &N4sidSettings {
            order: Some(order),
            ..Default::default()
        },
    )
    .unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic;
    use nalgebra::DMatrix;

    fn max_tf_error(a: &InnovationModel, b: &InnovationModel) -> f64 {
        (0..40)
            .map(|i| {
                let w = std::f64::consts::PI * i as f64 / 40.0;
                let ga = a.frequency_response(w).unwrap();
                let gb = b.frequency_response(w).unwrap();
                (ga - &gb).norm() / gb.norm()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn noise_free_data_recover_the_system_for_every_weighting_estimate_and_past() {
        let truth = synthetic::random_model(4, 2, 2, 11, 0.85);
        let mut det = truth.clone();
        det.k.fill(0.0);
        let data = synthetic::simulate(&det, 600, 0.0, 2).unwrap();
        for w in [Weighting::Moesp, Weighting::Cva, Weighting::Unweighted] {
            for (matrices, past) in [
                (MatrixEstimate::OutputError, None),
                (MatrixEstimate::StateRegression, None),
                (MatrixEstimate::StateRegression, Some(15)),
                (MatrixEstimate::OutputError, Some(15)),
            ] {
                let r = n4sid(
                    &data,
                    &N4sidSettings {
                        weighting: w,
                        max_order: 8,
                        past_horizon: past,
                        matrices,
                        ..Default::default()
                    },
                )
                .unwrap();
                assert_eq!(
                    r.suggested_order, 4,
                    "{w:?} {matrices:?} {past:?}: {:?}",
                    r.singular_values
                );
                let err = max_tf_error(&r.model, &det);
                assert!(err < 1e-6, "{w:?} {matrices:?} {past:?}: {err}");
            }
        }
    }

    /// One-step prediction error variance of `m` on `data`, from the
    /// predictor's least-squares initial state.
    fn one_step_mse(m: &InnovationModel, data: &IoData) -> f64 {
        let e = &data.experiments()[0];
        let x0 = crate::validate::estimate_x0_predictor(m, &e.u, &e.y).unwrap();
        let r = m.predict_one_step(&e.u, &e.y, &x0).unwrap().residuals;
        r.norm_squared() / r.len() as f64
    }

    #[test]
    fn state_regression_estimates_the_noise_model() {
        // Coloured noise (a large K): the state-sequence regression gives
        // both the dynamics and a one-step predictor close to the true
        // Kalman predictor's on fresh data.
        let mut truth = synthetic::random_model(3, 2, 2, 5, 0.9);
        truth.k *= 3.0;
        assert!(truth.radius_predictor() < 1.0);
        let data = synthetic::simulate(&truth, 5000, 0.3, 9).unwrap();
        let fresh = synthetic::simulate(&truth, 5000, 0.3, 10).unwrap();
        let best = one_step_mse(&truth, &fresh);
        for past in [None, Some(20)] {
            let r = n4sid(
                &data,
                &N4sidSettings {
                    order: Some(3),
                    past_horizon: past,
                    matrices: MatrixEstimate::StateRegression,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!(max_tf_error(&r.model, &truth) < 0.1, "{past:?}");
            assert!(r.model.radius_predictor() < 1.0);
            let mse = one_step_mse(&r.model, &fresh);
            assert!(mse < 1.03 * best, "{past:?}: {mse} vs {best}");
        }
    }

    #[test]
    fn noisy_data_give_a_close_model_with_a_stable_predictor() {
        let truth = synthetic::random_model(3, 2, 2, 5, 0.9);
        let data = synthetic::simulate(&truth, 5000, 0.2, 9).unwrap();
        let r = n4sid_of_order(&data, 3);
        assert!(max_tf_error(&r.model, &truth) < 0.1);
        assert!(r.model.radius_predictor() < 1.0);
    }

    #[test]
    fn bad_data_are_errors() {
        let truth = synthetic::random_model(3, 2, 2, 5, 0.9);
        let data = synthetic::simulate(&truth, 30, 0.1, 1).unwrap();
        let e = n4sid(
            &data,
            &N4sidSettings {
                order: Some(3),
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(matches!(e, SysidError::TooFewSamples { .. }), "{e}");
        let u = DMatrix::from_fn(
            500,
            2,
            |k, j| if j == 0 { ((k * 7) % 13) as f64 } else { 1.0 },
        );
        let y = DMatrix::from_fn(500, 1, |k, _| ((k * 5) % 11) as f64);
        let d = IoData::new(1.0, u, y).unwrap();
        let e = n4sid(&d, &N4sidSettings::default()).unwrap_err();
        assert!(matches!(e, SysidError::ConstantInput { .. }), "{e}");
        assert!(
            n4sid(
                &data,
                &N4sidSettings {
                    order: Some(0),
                    ..Default::default()
                }
            )
            .is_err()
        );
        let past0 = N4sidSettings {
            order: Some(3),
            past_horizon: Some(0),
            ..Default::default()
        };
        assert!(matches!(
            n4sid(&data, &past0),
            Err(SysidError::InvalidArgument(_))
        ));
        let long_past = N4sidSettings {
            order: Some(2),
            max_order: 2,
            horizon: Some(3),
            past_horizon: Some(20),
            ..Default::default()
        };
        let e = n4sid(&data, &long_past).unwrap_err();
        assert!(matches!(e, SysidError::TooFewSamples { .. }), "{e}");
        assert!(
            n4sid(
                &data,
                &N4sidSettings {
                    horizon: Some(1),
                    ..Default::default()
                }
            )
            .is_err()
        );
    }
}
