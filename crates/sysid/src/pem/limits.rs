//! Size limits of [`pem`](crate::pem()), checked before the first
//! Jacobian is built.
//!
//! Every Levenberg-Marquardt iteration forms the Jacobian row of every
//! residual: `ny` per sample and prediction step, so about
//! `N h ny` rows for a prediction horizon `h` (up to `N^2 ny / 2` when
//! `h` reaches the length `N` of the data), times the parameters `p`
//! (about `n^2` for order `n`). Adding them to `J'J` costs `p^2`
//! operations per residual. The rows are accumulated into `J'J` a block
//! at a time and never stored together, but the limits are still
//! stated as the size of that whole Jacobian: they bound the work of an
//! iteration (and keep refusing what they refused before).

use crate::error::{Result, SizedMethod, SysidError};

/// Largest size of the Jacobian of one PEM iteration (8 bytes per
/// entry, residuals x parameters): 1 GiB. The search no longer stores
/// it whole (see the module docs); the limit bounds the rows formed.
pub const MAX_PEM_JACOBIAN_BYTES: f64 = (1u64 << 30) as f64;

/// Largest number of operations of one PEM iteration (the Jacobian and
/// the normal equations `J'J`), estimated as `residuals x p x (p + n^2)`:
/// `5e10`, some ten seconds per iteration.
pub const MAX_PEM_FLOPS_PER_ITERATION: f64 = 5e10;

/// Refuses a search with `residuals` residuals, `p` parameters and order
/// `n` whose iterations exceed [`MAX_PEM_JACOBIAN_BYTES`] or
/// [`MAX_PEM_FLOPS_PER_ITERATION`]; `h` is the prediction horizon, for
/// the message.
pub(super) fn check_size(residuals: usize, p: usize, n: usize, h: usize) -> Result<()> {
    let (r, pf, nf) = (residuals as f64, p as f64, n as f64);
    let bytes = 8.0 * r * pf;
    let flops = r * pf * (pf + nf * nf);
    if bytes <= MAX_PEM_JACOBIAN_BYTES && flops <= MAX_PEM_FLOPS_PER_ITERATION {
        return Ok(());
    }
    Err(SysidError::TooLarge {
        method: SizedMethod::Pem,
        what: format!("PEM of order {n} with prediction horizon {h}"),
        cost: format!(
            "a Jacobian of {residuals} residuals x {p} parameters ({:.1} GB) and about {flops:.0e} operations per iteration",
            bytes / 1e9
        ),
        limit: format!(
            "at most {:.1} GB and {MAX_PEM_FLOPS_PER_ITERATION:.0e} operations per iteration",
            MAX_PEM_JACOBIAN_BYTES / 1e9
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_horizons_and_high_orders_are_refused() {
        // The pipeline's fit: order 5, 4 inputs, 3 outputs, 12,000 samples, h = 1.
        assert!(check_size(36_000, 95, 5, 1).is_ok());
        // h = 20 on the same data.
        assert!(check_size(720_000, 95, 5, 20).is_ok());
        // h = 5000 on 3,000 samples: N^2 ny / 2 residuals.
        let e = check_size(13_500_000, 95, 5, 5000).unwrap_err();
        assert!(
            matches!(
                e,
                SysidError::TooLarge {
                    method: SizedMethod::Pem,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("horizon 5000"), "{e}");
    }
}
