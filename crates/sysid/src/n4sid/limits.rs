//! Size limits of [`n4sid`](crate::n4sid()), checked before the work
//! they bound starts.
//!
//! The cost of N4SID grows with the model order `n`: the block Hankel
//! matrix has `2 i (nu + ny)` rows with a horizon `i > n / ny`, and the
//! output-error fit of `B`, `D` and the initial states simulates the
//! model once per unknown, about `N n^3 nu` operations on `N` samples.
//! An order of several hundred on a few thousand samples would run for
//! hours and could not be determined by the data anyway.

use crate::error::{Result, SizedMethod, SysidError};

/// Largest model order [`n4sid`](crate::n4sid()) identifies (the
/// tricopter's models have 5 to 9 states; the DaISy benchmarks up to 10).
pub const MAX_ORDER: usize = 100;

/// Largest memory of the block Hankel matrix (8 bytes per entry): 1 GiB.
pub const MAX_HANKEL_BYTES: f64 = (1u64 << 30) as f64;

/// Free parameters of an innovation model of order `n` with `nu` inputs
/// and `ny` outputs: `A` (n x n), `B` (n x nu), `C` (ny x n), `K`
/// (n x ny) and `D` (ny x nu).
///
/// ```
/// assert_eq!(kestrel_sysid::model_parameters(5, 4, 3), 25 + 20 + 15 + 15 + 12);
/// ```
pub fn model_parameters(n: usize, nu: usize, ny: usize) -> usize {
    n.saturating_mul(n.saturating_add(nu).saturating_add(2 * ny))
        .saturating_add(ny * nu)
}

/// Refuses an order above [`MAX_ORDER`], or one whose model has more
/// parameters ([`model_parameters`]) than the data have output values
/// (`samples x ny`): such a model is not determined by the data.
pub(super) fn check_order(n: usize, nu: usize, ny: usize, samples: usize) -> Result<()> {
    let values = samples.saturating_mul(ny);
    let params = model_parameters(n, nu, ny);
    if n <= MAX_ORDER && params <= values {
        return Ok(());
    }
    // The largest order these data determine.
    let fits = (1..=MAX_ORDER)
        .take_while(|&k| model_parameters(k, nu, ny) <= values)
        .last()
        .unwrap_or(0);
    Err(SysidError::TooLarge {
        method: SizedMethod::N4sid,
        what: format!("N4SID of order {n}"),
        cost: format!(
            "{params} parameters against {values} output values ({samples} samples x {ny} outputs) and about {:.0e} operations",
            samples as f64 * (n as f64).powi(3) * (nu.max(1) as f64)
        ),
        limit: format!(
            "at most order {MAX_ORDER}, and no more parameters than output values: order {fits} for these data"
        ),
    })
}

/// Refuses a block Hankel matrix of `rows x cols` above [`MAX_HANKEL_BYTES`].
pub(super) fn check_hankel(rows: usize, cols: usize) -> Result<()> {
    let bytes = 8.0 * rows as f64 * cols as f64;
    if bytes <= MAX_HANKEL_BYTES {
        return Ok(());
    }
    Err(SysidError::TooLarge {
        method: SizedMethod::N4sid,
        what: format!("an N4SID block Hankel matrix of {rows} x {cols}"),
        cost: format!("{:.1} GB of memory", bytes / 1e9),
        limit: format!("at most {:.1} GB", MAX_HANKEL_BYTES / 1e9),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_beyond_the_data_or_the_limit_are_refused() {
        assert!(check_order(5, 4, 3, 3000).is_ok());
        assert!(check_order(10, 4, 3, 700).is_ok());
        let e = check_order(500, 4, 3, 3000).unwrap_err();
        assert!(
            matches!(
                e,
                SysidError::TooLarge {
                    method: SizedMethod::N4sid,
                    ..
                }
            ),
            "{e}"
        );
        let text = e.to_string();
        assert!(
            text.contains("order 500") && text.contains("order 89"),
            "{text}"
        );
        assert!(check_order(101, 4, 3, 1_000_000).is_err());
        assert!(check_hankel(2352, 2665).is_ok());
        assert!(check_hankel(2352, 1_000_000).is_err());
    }
}
