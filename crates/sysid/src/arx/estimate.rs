//! The least-squares fit of [`arx`].

use super::model::{ArxModel, ArxSettings};
use crate::data::IoData;
use crate::error::{Result, SizedMethod, SysidError};
use nalgebra::{DMatrix, DVector};

/// Rows of a regression matrix built at a time (bounds the memory to
/// `CHUNK x parameters` values whatever the data length; also the
/// feedback test's).
pub(crate) const CHUNK: usize = 4096;

/// Smallest ratio of the smallest to the largest eigenvalue of the
/// normalised normal-equation matrix: below it the regressors are taken
/// as linearly dependent and the fit is refused.
pub(crate) const MIN_RCOND: f64 = 1e-13;

/// The regressor `phi(t) = [y(t-1); ..; y(t-na); u(t-nk); ..; u(t-nk-nb+1)]`
/// of sample `t` (which must have `t >= max_lag`) written into `out`.
pub(crate) fn regressor(
    s: &ArxSettings,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
    t: usize,
    out: &mut [f64],
) {
    let (nu, ny) = (u.ncols(), y.ncols());
    let mut c = 0;
    for i in 1..=s.na {
        for o in 0..ny {
            out[c] = y[(t - i, o)];
            c += 1;
        }
    }
    for j in 0..s.nb {
        for q in 0..nu {
            out[c] = u[(t - s.nk - j, q)];
            c += 1;
        }
    }
}

/// The most operations (rows x parameters per output squared) an ARX fit
/// may take, the budget of one PEM iteration
/// ([`MAX_PEM_FLOPS_PER_ITERATION`](crate::MAX_PEM_FLOPS_PER_ITERATION));
/// about a minute. 500 Hz logs with 10 lags take 1e8-1e9.
pub const MAX_ARX_OPERATIONS: f64 = 5e10;

/// MIMO ARX by linear least squares over every experiment of `data`
/// (MATLAB's `arx`): each output's equation
/// `y(t) = sum a_i y(t-i) + sum b_j u(t-nk-j) + e(t)` is one regression
/// on the same regressors, every sample `t` with a full history
/// (`t >= max_lag` within its experiment; experiments are never joined)
/// is one row. The signals are scaled to unit variance and the normal
/// equations are solved by Cholesky after a conditioning check, so
/// the cost is one pass over the data (`N p^2` for `p = ny na + nu nb`
/// parameters per output) and the memory `O(p^2)`.
///
/// Errors: `na = nb = 0`; a constant input or output
/// ([`SysidError::ConstantInput`], [`SysidError::ConstantOutput`]);
/// fewer regression rows than `p + 1` ([`SysidError::TooFewSamples`]);
/// more than [`MAX_ARX_OPERATIONS`] (`rows p^2`, [`SysidError::TooLarge`],
/// before the pass over the data);
/// linearly dependent regressors, e.g. two identical inputs
/// ([`SysidError::Numerical`]).
///
/// ```
/// use kestrel_sysid::{arx, synthetic, ArxSettings};
/// let truth = synthetic::random_model(2, 2, 2, 3, 0.8);
/// let data = synthetic::simulate(&truth, 3000, 0.05, 1).unwrap();
/// let model = arx(&data, &ArxSettings::lags(4)).unwrap();
/// assert_eq!((model.a().len(), model.b().len()), (4, 4));
/// // One-step fit in percent per output; an exact state-space realisation.
/// let fit = model.predict_fit(&data, 1).unwrap();
/// assert!(fit.iter().all(|f| *f > 80.0));
/// assert_eq!(model.to_innovation_model().unwrap().nx(), 2 * 4);
/// ```
pub fn arx(data: &IoData, settings: &ArxSettings) -> Result<ArxModel> {
    arx_with_normal_equations(data, settings).map(|(m, _)| m)
}

/// [`arx`] and the normal equations it solved (the closed-loop methods
/// weigh their past data with the regressors' covariance).
pub(crate) fn arx_with_normal_equations(
    data: &IoData,
    settings: &ArxSettings,
) -> Result<(ArxModel, NormalEquations)> {
    let (nu, ny) = (data.nu(), data.ny());
    let ne = NormalEquations::of(data, settings)?;
    let theta = solve_normal_equations(&ne.gram, &ne.cross)?;
    // Residual covariance from the normal equations:
    // E'E = Y'Y - Theta' Phi'Y (Theta solves them exactly).
    let mut lambda = (&ne.yy - theta.tr_mul(&ne.cross)) / ne.rows as f64;
    lambda = (&lambda + lambda.transpose()) * 0.5;
    let sy = &ne.sy;
    // Back to the units of the data: a_i = Sy a_i,s Sy^-1, b_j = Sy b_j,s Su^-1.
    let coef = |j: usize, o: usize| theta[(j, o)] * ne.scale[j] * sy[o];
    let mut a = Vec::with_capacity(settings.na);
    let mut c = 0;
    for _ in 0..settings.na {
        a.push(DMatrix::from_fn(ny, ny, |o, i| coef(c + i, o)));
        c += ny;
    }
    let mut b = Vec::with_capacity(settings.nb);
    for _ in 0..settings.nb {
        b.push(DMatrix::from_fn(ny, nu, |o, q| coef(c + q, o)));
        c += nu;
    }
    let lambda = DMatrix::from_fn(ny, ny, |i, j| lambda[(i, j)] * sy[i] * sy[j]);
    let model = ArxModel::new(data.ts(), *settings, nu, ny, a, b)?.with_noise_covariance(lambda);
    Ok((model, ne))
}

/// The normal equations of an ARX regression on the signals scaled to
/// unit variance: `gram = Phi' Phi`, `cross = Phi' Y`, `yy = Y' Y` with
/// `Phi` the scaled regressors (column `j` of [`regressor`] times
/// `scale[j]`) and `Y` the outputs divided by `sy`.
pub(crate) struct NormalEquations {
    pub(crate) gram: DMatrix<f64>,
    pub(crate) cross: DMatrix<f64>,
    pub(crate) yy: DMatrix<f64>,
    pub(crate) scale: DVector<f64>,
    pub(crate) sy: DVector<f64>,
    pub(crate) rows: usize,
}

impl NormalEquations {
    /// One pass over the data (errors as [`arx`]).
    pub(crate) fn of(data: &IoData, settings: &ArxSettings) -> Result<Self> {
        settings.check()?;
        let (nu, ny) = (data.nu(), data.ny());
        let (su, sy) = data.check_excitation()?;
        let p = settings.parameters_per_output(nu, ny);
        let lag = settings.max_lag();
        let rows = settings.regression_rows(data);
        let operations = rows as f64 * (p as f64).powi(2);
        if operations > MAX_ARX_OPERATIONS {
            return Err(SysidError::TooLarge {
                method: SizedMethod::Arx,
                what: format!(
                    "ARX with na = {}, nb = {} ({p} parameters per output)",
                    settings.na, settings.nb
                ),
                cost: format!("about {operations:.0e} operations for its {rows} rows"),
                limit: format!("at most {MAX_ARX_OPERATIONS:.0e}; use fewer lags"),
            });
        }
        if rows < p + 1 {
            return Err(SysidError::TooFewSamples {
                what: format!(
                    "ARX with na = {}, nb = {}, nk = {} ({p} parameters per output, {lag} lags)",
                    settings.na, settings.nb, settings.nk
                ),
                needed: p + 1 + lag,
                found: data.n_samples(),
            });
        }
        // Regressor scale: every signal to unit variance.
        let mut scale = DVector::zeros(p);
        let mut c = 0;
        for _ in 0..settings.na {
            for o in 0..ny {
                scale[c] = 1.0 / sy[o];
                c += 1;
            }
        }
        for _ in 0..settings.nb {
            for q in 0..nu {
                scale[c] = 1.0 / su[q];
                c += 1;
            }
        }
        let mut gram = DMatrix::<f64>::zeros(p, p);
        let mut cross = DMatrix::<f64>::zeros(p, ny);
        let mut yy = DMatrix::<f64>::zeros(ny, ny);
        let mut row = vec![0.0; p];
        for e in data.experiments() {
            let n = e.len();
            let mut t0 = lag;
            while t0 < n {
                let m = CHUNK.min(n - t0);
                let mut phi = DMatrix::<f64>::zeros(m, p);
                let mut yt = DMatrix::<f64>::zeros(m, ny);
                for r in 0..m {
                    regressor(settings, &e.u, &e.y, t0 + r, &mut row);
                    for (j, v) in row.iter().enumerate() {
                        phi[(r, j)] = v * scale[j];
                    }
                    for o in 0..ny {
                        yt[(r, o)] = e.y[(t0 + r, o)] / sy[o];
                    }
                }
                gram += phi.tr_mul(&phi);
                cross += phi.tr_mul(&yt);
                yy += yt.tr_mul(&yt);
                t0 += m;
            }
        }
        Ok(NormalEquations {
            gram,
            cross,
            yy,
            scale,
            sy,
            rows,
        })
    }
}

/// Solves `G theta = R` for a symmetric positive definite `G` by
/// Cholesky, after checking its conditioning (eigenvalues of `G`
/// normalised to unit diagonal).
pub(crate) fn solve_normal_equations(
    gram: &DMatrix<f64>,
    cross: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let p = gram.nrows();
    let d = DVector::from_fn(p, |i, _| {
        let g = gram[(i, i)];
        if g > 0.0 { 1.0 / g.sqrt() } else { 0.0 }
    });
    if let Some(i) = d.iter().position(|v| *v == 0.0) {
        return Err(SysidError::Numerical(format!(
            "regressor {i} is zero on every row (no excitation)"
        )));
    }
    let g = DMatrix::from_fn(p, p, |i, j| gram[(i, j)] * d[i] * d[j]);
    if g.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(
            "the normal equations have a non-finite entry".into(),
        ));
    }
    let eig = g.clone().symmetric_eigen();
    let (lmin, lmax) = (eig.eigenvalues.min(), eig.eigenvalues.max());
    let well_conditioned = lmin > MIN_RCOND * lmax; // false for NaN too
    if !well_conditioned {
        return Err(SysidError::Numerical(format!(
            "the regressors are linearly dependent (reciprocal condition {:.1e} of the \
             normalised normal equations, below {MIN_RCOND:.0e}): an input that is a \
             combination of others, or lags that carry no new information",
            (lmin / lmax).max(0.0)
        )));
    }
    let chol = g
        .cholesky()
        .ok_or_else(|| SysidError::Numerical("normal equations not positive definite".into()))?;
    let rhs = DMatrix::from_fn(p, cross.ncols(), |i, j| cross[(i, j)] * d[i]);
    let x = chol.solve(&rhs);
    let theta = DMatrix::from_fn(p, cross.ncols(), |i, j| x[(i, j)] * d[i]);
    if theta.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(
            "least-squares solution is not finite".into(),
        ));
    }
    Ok(theta)
}
