//! A model identified at a log's native rate, resampled to a slower
//! control rate: [`resample_model`].

use crate::error::{Result, SysidError};
use crate::model::InnovationModel;

/// The factor `m = ts_new / ts` when it is an integer `>= 1` (within
/// `1e-6` relative), else an error naming both rates.
pub fn rate_factor(ts: f64, ts_new: f64) -> Result<usize> {
    let r = ts_new / ts;
    let m = r.round();
    if !(r.is_finite() && m >= 1.0 && (r - m).abs() <= 1e-6 * m) {
        return Err(SysidError::invalid(format!(
            "the model rate {:.6} Hz must divide the identification rate {:.6} Hz by an integer (ratio {r})",
            1.0 / ts_new,
            1.0 / ts
        )));
    }
    Ok(m as usize)
}

/// `model` (sample time `ts`) at the sample time `m ts` for inputs held
/// over the `m` fast samples (zero-order hold at the slow rate): exactly
/// `A_m = A^m`, `B_m = (A^(m-1) + ... + A + I) B`, `C` and `D` unchanged,
/// so the slow model's step response equals the fast one's at every
/// `m`-th sample. The noise model maps to `K_m = A^(m-1) K`: the fast
/// predictor's correction at the measured sample carried over the
/// `m - 1` unmeasured ones (a stable predictor when `A - KC` is, not the
/// slow rate's optimal gain; refit `K` at the slow rate when it
/// matters). `m = 1` returns the model unchanged.
///
/// ```
/// use kestrel_sysid::{synthetic, workflow::resample_model};
/// let fast = synthetic::random_model(3, 2, 1, 5, 0.95);
/// let slow = resample_model(&fast, 10).unwrap();
/// assert!((slow.ts - 10.0 * fast.ts).abs() < 1e-12);
/// ```
pub fn resample_model(model: &InnovationModel, m: usize) -> Result<InnovationModel> {
    if m == 0 {
        return Err(SysidError::invalid("the resampling factor must be >= 1"));
    }
    let n = model.nx();
    let mut power = nalgebra::DMatrix::identity(n, n); // A^i
    let mut sum = nalgebra::DMatrix::zeros(n, n); // I + A + ... + A^(i-1)
    let mut k = model.k.clone();
    for i in 0..m {
        sum += &power;
        if i + 1 < m {
            power = &model.a * &power;
            k = &model.a * &k;
        }
    }
    let a = &model.a * &power;
    InnovationModel::new(
        model.ts * m as f64,
        a,
        sum * &model.b,
        model.c.clone(),
        model.d.clone(),
        k,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic;
    use nalgebra::{DMatrix, DVector};

    /// Inputs held over `m` fast samples: the fast simulation at every
    /// `m`-th sample equals the slow model's simulation (an independent
    /// computation of the same response); a non-integer ratio is refused.
    #[test]
    fn resampled_model_matches_the_fast_one_at_the_slow_samples() {
        let fast = synthetic::random_model(4, 2, 2, 7, 0.97);
        let m = 10;
        let slow = resample_model(&fast, m).unwrap();
        let steps = 30;
        let us = DMatrix::from_fn(steps, 2, |t, j| ((t * 7 + j * 3) % 5) as f64 - 2.0);
        let uf = DMatrix::from_fn(steps * m, 2, |t, j| us[(t / m, j)]);
        let x0 = DVector::from_element(4, 0.3);
        let yf = fast.simulate(&uf, &x0).unwrap();
        let ys = slow.simulate(&us, &x0).unwrap();
        for t in 0..steps {
            for j in 0..2 {
                let (a, b) = (ys[(t, j)], yf[(t * m, j)]);
                assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()), "{t} {j}: {a} {b}");
            }
        }
        assert_eq!(resample_model(&fast, 1).unwrap(), fast);
        assert_eq!(rate_factor(0.002, 0.02).unwrap(), 10);
        assert!(rate_factor(0.002, 0.0205).is_err());
        assert!(rate_factor(0.02, 0.002).is_err());
    }
}
