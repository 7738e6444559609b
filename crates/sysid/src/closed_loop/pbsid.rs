//! Predictor-based subspace identification (PBSID) from a VARX step.

use super::settings::{PBSID_PAST, PbsidResult, PbsidSettings};
use super::stabilise::pull_inside;
use crate::arx::{ArxSettings, arx_with_normal_equations, default_lags};
use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::{lstsq, spectral_radius};
use crate::model::InnovationModel;
use crate::n4sid::{MAX_ORDER, Scaling, model_parameters, stabilise_k, suggest_order};
use nalgebra::{DMatrix, DVector};

/// Predictor-based subspace identification (Chiuso's PBSID; van der
/// Veen, van Wingerden, Bergamasco, Lovera and Verhaegen, "Closed-loop
/// subspace identification methods: an overview", IET Control Theory &
/// Applications 7(10), 2013), consistent on closed-loop data.
///
/// The innovation form written as its one-step predictor,
/// `x(t+1) = (A - K C) x(t) + (B - K D) u(t) + K y(t)`, has a state that
/// is a linear function of the past inputs and outputs once
/// `(A - K C)^p` is negligible: `x(t) ~ K_p z_p(t)` with
/// `z_p(t) = [z(t-1); ..; z(t-p)]`, `z = [u; y]`. Steps:
///
/// 1. a VARX of order `p` (the ARX least squares of [`arx`](crate::arx())
///    with `na = nb = p`) estimates the predictor's Markov parameters
///    `Xi_i = C (A - KC)^(i-1) [B - KD, K]`; the regression of `y(t)` on
///    the past is consistent whether or not the inputs react to the
///    noise, because the innovation `e(t)` is uncorrelated with the past
///    (this is where MOESP and CVA, which project on the future inputs,
///    are biased in closed loop);
/// 2. the product of the predictor's observability and controllability
///    matrices `Gamma_f K_p` is assembled from them (block `(j, i)` is
///    `Xi_(i+j)`, zero beyond `p`), weighted by the square root of the
///    covariance of the past and factored by an SVD: the leading
///    singular vectors give the order and the state sequence
///    `x(t) = S_n^(-1/2) U_n' Gamma_f K_p z_p(t)`;
/// 3. `C` and `D` are the least squares of `y(t)` on `x(t)` (and `u(t)`),
///    their residuals the innovations `e(t)`, and `A`, `B`, `K` the least
///    squares of `x(t+1)` on `x(t)`, `u(t)` and `e(t)`.
///
/// Every signal is scaled to unit variance inside; the model is returned
/// in the units of the data, `K` shrunk only if `A - K C` would be
/// unstable. The cost is that of the VARX (`N p^2 (nu + ny)^2`) and one
/// pass for the states.
///
/// ```
/// use kestrel_sysid::{pbsid, synthetic, PbsidSettings};
/// let truth = synthetic::random_model(3, 2, 2, 1, 0.9);
/// let data = synthetic::simulate(&truth, 3000, 0.1, 7).unwrap();
/// let r = pbsid(&data, &PbsidSettings { order: Some(3), past: Some(15), ..Default::default() }).unwrap();
/// assert_eq!((r.order, r.model.nx()), (3, 3));
/// assert!(r.model.radius_predictor() < 1.0);
/// ```
pub fn pbsid(data: &IoData, settings: &PbsidSettings) -> Result<PbsidResult> {
    let (nu, ny) = (data.nu(), data.ny());
    let nz = nu + ny;
    if settings.order == Some(0) {
        return Err(SysidError::invalid("model order must be >= 1"));
    }
    let nmax = settings.order.unwrap_or(settings.max_order).max(1);
    let feed = settings.feedthrough;
    let varx_settings = |p: usize| ArxSettings {
        na: p,
        nb: if feed { p + 1 } else { p },
        nk: usize::from(!feed),
    };
    let p = settings.past.unwrap_or_else(|| {
        let least = settings.future.unwrap_or(0).max(nmax / ny + 1);
        default_lags(data, PBSID_PAST, least, varx_settings)
    });
    let f = settings.future.unwrap_or(p);
    if p == 0 || f == 0 || f > p {
        return Err(SysidError::invalid(format!(
            "PBSID horizons past {p}, future {f}: need 1 <= future <= past"
        )));
    }
    if nmax >= f * ny {
        return Err(SysidError::invalid(format!(
            "PBSID order {nmax} needs future * outputs > order (future {f}, {ny} outputs)"
        )));
    }
    check_order(nmax, nu, ny, data.n_samples())?;
    let scaling = Scaling::of(data)?;
    let sdata = data.scaled(&scaling.su, &scaling.sy);
    let varx_settings = varx_settings(p);
    let (varx, ne) = arx_with_normal_equations(&sdata, &varx_settings)?;
    // Xi_i = [b at lag i, a_i] for lags 1..=p (z = [u; y]).
    let xi: Vec<DMatrix<f64>> = (1..=p)
        .map(|i| {
            let mut m = DMatrix::zeros(ny, nz);
            if let Some(b) = varx.b_at_lag(i) {
                m.columns_mut(0, nu).copy_from(b);
            }
            if let Some(a) = varx.a_at_lag(i) {
                m.columns_mut(nu, ny).copy_from(a);
            }
            m
        })
        .collect();
    let mut h = DMatrix::zeros(f * ny, p * nz);
    for j in 0..f {
        for i in 1..=p - j {
            h.view_mut((j * ny, (i - 1) * nz), (ny, nz))
                .copy_from(&xi[i + j - 1]);
        }
    }
    // Covariance of the past z_p from the VARX's normal equations (the
    // regressors are [y lags 1..p, u lags nk..]; scaled by `ne.scale`).
    let gram_index = |k: usize| -> usize {
        let (lag, c) = (k / nz + 1, k % nz);
        if c < nu {
            ny * p + (lag - varx_settings.nk) * nu + c
        } else {
            (lag - 1) * ny + (c - nu)
        }
    };
    let dim = p * nz;
    let sigma = DMatrix::from_fn(dim, dim, |r, c| {
        let (gr, gc) = (gram_index(r), gram_index(c));
        ne.gram[(gr, gc)] / (ne.scale[gr] * ne.scale[gc] * ne.rows as f64)
    });
    let l = sigma
        .cholesky()
        .ok_or_else(|| {
            SysidError::Numerical("covariance of the past is not positive definite".into())
        })?
        .l();
    let svd = (&h * &l).svd(true, false);
    let u = svd
        .u
        .ok_or_else(|| SysidError::Numerical("SVD failed".into()))?;
    let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
    idx.sort_by(|a, b| svd.singular_values[*b].total_cmp(&svd.singular_values[*a]));
    let sv: Vec<f64> = idx.iter().map(|&k| svd.singular_values[k]).collect();
    let suggested = suggest_order(&sv, settings.max_order.min(f * ny - 1));
    let n = settings.order.unwrap_or(suggested);
    check_order(n, nu, ny, data.n_samples())?;
    if !sv.get(n - 1).is_some_and(|s| *s > 0.0) {
        return Err(SysidError::Numerical(format!(
            "PBSID: singular value {n} is zero; the data determine fewer than {n} states"
        )));
    }
    let mut m = DMatrix::zeros(n, dim);
    for (r, &k) in idx.iter().take(n).enumerate() {
        let row = u.column(k).transpose() * &h / sv[r].sqrt();
        m.row_mut(r).copy_from(&row);
    }
    if let Some(r) = settings.max_radius
        && !(r.is_finite() && r > 0.0)
    {
        return Err(SysidError::invalid(format!(
            "PBSID max_radius must be finite and > 0, found {r}"
        )));
    }
    let (model, radius_estimated) = state_regressions(&sdata, &m, p, n, feed, settings.max_radius)?;
    Ok(PbsidResult {
        radius_estimated,
        model: scaling.unscale(&model),
        singular_values: sv,
        suggested_order: suggested,
        order: n,
        past: p,
        future: f,
    })
}

/// An order above [`MAX_ORDER`] or with more parameters than output
/// values is refused (as [`n4sid`](crate::n4sid()) does).
fn check_order(n: usize, nu: usize, ny: usize, samples: usize) -> Result<()> {
    let params = model_parameters(n, nu, ny);
    if n > MAX_ORDER || params > samples.saturating_mul(ny) {
        return Err(SysidError::TooFewSamples {
            what: format!(
                "a PBSID model of order {n} ({params} parameters, at most order {MAX_ORDER})"
            ),
            needed: params.div_ceil(ny.max(1)),
            found: samples,
        });
    }
    Ok(())
}

/// Step 3: the states `x(t) = M z_p(t)` of every experiment, then `C`,
/// `D` and the innovations, then `A`, `B`, `K`.
fn state_regressions(
    data: &IoData,
    m: &DMatrix<f64>,
    p: usize,
    n: usize,
    feed: bool,
    max_radius: Option<f64>,
) -> Result<(InnovationModel, f64)> {
    let (nu, ny) = (data.nu(), data.ny());
    let nz = nu + ny;
    let mut xs = Vec::new(); // per experiment: n x len, the states at t = p..N
    let mut zp = DVector::zeros(p * nz);
    for e in data.experiments() {
        let len = e.len().saturating_sub(p);
        let mut x = DMatrix::zeros(n, len);
        for c in 0..len {
            let t = p + c;
            for i in 1..=p {
                for q in 0..nu {
                    zp[(i - 1) * nz + q] = e.u[(t - i, q)];
                }
                for o in 0..ny {
                    zp[(i - 1) * nz + nu + o] = e.y[(t - i, o)];
                }
            }
            x.column_mut(c).copy_from(&(m * &zp));
        }
        xs.push(x);
    }
    let total: usize = xs.iter().map(|x| x.ncols()).sum();
    let pairs: usize = xs.iter().map(|x| x.ncols().saturating_sub(1)).sum();
    if pairs <= n + nu + ny {
        return Err(SysidError::TooFewSamples {
            what: format!("PBSID state regressions (order {n}, past {p})"),
            needed: p + n + nu + ny + 2,
            found: data.n_samples(),
        });
    }
    // [C D]: y(t) = C x(t) + D u(t) + e(t).
    let nr = n + if feed { nu } else { 0 };
    let mut reg = DMatrix::zeros(total, nr);
    let mut yt = DMatrix::zeros(total, ny);
    let mut r0 = 0;
    for (e, x) in data.experiments().iter().zip(&xs) {
        for c in 0..x.ncols() {
            reg.view_mut((r0 + c, 0), (1, n))
                .copy_from(&x.column(c).transpose());
            if feed {
                reg.view_mut((r0 + c, n), (1, nu))
                    .copy_from(&e.u.row(p + c));
            }
            yt.row_mut(r0 + c).copy_from(&e.y.row(p + c));
        }
        r0 += x.ncols();
    }
    let cd = lstsq(&reg, &yt).transpose();
    let c_mat = cd.columns(0, n).into_owned();
    let d = if feed {
        cd.columns(n, nu).into_owned()
    } else {
        DMatrix::zeros(ny, nu)
    };
    let innov = &yt - &reg * cd.transpose();
    // [A B K]: x(t+1) = A x(t) + B u(t) + K e(t), pairs within experiments.
    let mut reg2 = DMatrix::zeros(pairs, n + nu + ny);
    let mut xn = DMatrix::zeros(pairs, n);
    let (mut r0, mut row) = (0, 0);
    for (e, x) in data.experiments().iter().zip(&xs) {
        for c in 0..x.ncols().saturating_sub(1) {
            reg2.view_mut((row, 0), (1, n))
                .copy_from(&x.column(c).transpose());
            reg2.view_mut((row, n), (1, nu)).copy_from(&e.u.row(p + c));
            reg2.view_mut((row, n + nu), (1, ny))
                .copy_from(&innov.row(r0 + c));
            xn.row_mut(row).copy_from(&x.column(c + 1).transpose());
            row += 1;
        }
        r0 += x.ncols();
    }
    let abk = lstsq(&reg2, &xn).transpose();
    let mut a = abk.columns(0, n).into_owned();
    let mut bk = abk.columns(n, nu + ny).into_owned();
    let radius = spectral_radius(&a);
    if let Some(r) = max_radius
        && radius > r
    {
        a = pull_inside(&a, r);
        // B and K refitted with A fixed: x(t+1) - A x(t) = [B K] [u; e].
        let lhs = &xn - reg2.columns(0, n) * a.transpose();
        bk = lstsq(&reg2.columns(n, nu + ny).into_owned(), &lhs).transpose();
    }
    let b = bk.columns(0, nu).into_owned();
    let k = stabilise_k(&a, &c_mat, bk.columns(nu, ny).into_owned());
    Ok((InnovationModel::new(data.ts(), a, b, c_mat, d, k)?, radius))
}
