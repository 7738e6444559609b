//! The subspace algorithm: block Hankel matrices, the oblique projection,
//! the weighted SVD and the system matrices.

use super::gain::stabilise_k;
use super::limits::{MAX_ORDER, check_hankel, check_order};
use super::order::suggest_order;
use super::output_error::{BdX0, fit_bd_x0};
use super::scaling::Scaling;
use super::settings::{MatrixEstimate, N4sidResult, N4sidSettings, Weighting};
use super::state_sequence::{Abcd, StateSequence};
use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::{self, inv_sqrt_spd, lstsq, pinv, r_factor, spectral_radius};
use crate::model::InnovationModel;
use crate::validate::estimate_x0_simulation;
use nalgebra::DMatrix;

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
/// Sizes are checked before the work starts: an order above
/// [`MAX_ORDER`](crate::MAX_ORDER), a model with more parameters
/// ([`model_parameters`](crate::model_parameters)) than the data have
/// output values, or a block Hankel matrix above
/// [`MAX_HANKEL_BYTES`](crate::MAX_HANKEL_BYTES) is refused with
/// [`SysidError::TooLarge`].
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
        None => default_horizon(&sdata, nmax, settings.past_horizon),
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
    let cols = hankel_columns(&sdata, i + p);
    if cols < rows {
        let needed = rows + i + p - 1;
        return Err(SysidError::TooFewSamples {
            what: format!("N4SID of order {nmax} with horizons {i}/{p} ({rows} Hankel rows)"),
            needed,
            found: data.n_samples(),
        });
    }
    // Too few samples for the Hankel matrix is the plainer message; then the
    // order against the data, then the memory.
    if let Some(n) = settings.order {
        check_order(n, nu, ny, data.n_samples())?;
    } else if nmax > MAX_ORDER {
        check_order(nmax, nu, ny, data.n_samples())?;
    }
    check_hankel(rows, cols)?;
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
    check_order(n, nu, ny, data.n_samples())?;
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

/// The default horizon `i`: `max(10, ceil((n_max + 1) / ny) + 1)`, or
/// on a record too short for its block Hankel matrix the largest shorter
/// one that fits and still has `i ny > n_max` (the shortest that does
/// not fit is reported by [`n4sid`]'s sample check).
fn default_horizon(data: &IoData, nmax: usize, past: Option<usize>) -> usize {
    let (nu, ny) = (data.nu(), data.ny().max(1));
    let longest = 10usize.max((nmax + 1).div_ceil(ny) + 1);
    let shortest = (nmax / ny + 1).max(2);
    let fits = |i: usize| {
        let p = past.unwrap_or(i);
        hankel_columns(data, i + p) >= (i + p) * (nu + ny)
    };
    (shortest..=longest)
        .rev()
        .find(|&i| fits(i))
        .unwrap_or(longest)
}

/// The block Hankel matrix's columns: `len + 1 - (i + p)` per experiment.
fn hankel_columns(data: &IoData, block_rows: usize) -> usize {
    data.experiments()
        .iter()
        .map(|e| (e.len() + 1).saturating_sub(block_rows))
        .sum()
}
