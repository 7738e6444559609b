//! Size limits of the condensing, checked before anything is allocated.
//!
//! The condensed problem of a horizon `N` with `nb` move blocks and `nu`
//! inputs has `n = nb * nu` decision variables: a dense `n x n` Hessian,
//! a `2n x n` constraint matrix and, while it is built, the prediction of
//! every step (`(N + 1) x nx x (n + p)` numbers). Without move blocking
//! `n = N * nu`, so a long horizon grows the memory with `N^3` and the
//! time with `N^3` as well: `--horizon 100000` would need terabytes.

use crate::error::MpcError;

/// Largest number of decision variables `n = blocks x inputs` that
/// [`MpcProblem::build`](crate::MpcProblem::build) condenses (its Hessian
/// alone is 8 MB at this size, and `kestrel mpc` writes a 35 MB file in
/// about ten seconds; the larger thesis problem has 16).
pub const MAX_DECISION_VARIABLES: usize = 1_000;

/// Largest memory the condensing may need, as estimated by
/// [`CondensingCost::of`]: 1 GiB.
pub const MAX_CONDENSING_BYTES: f64 = (1u64 << 30) as f64;

/// Largest number of floating-point operations the condensing may need,
/// as estimated by [`CondensingCost::of`]: `1e11` (a minute or two).
pub const MAX_CONDENSING_FLOPS: f64 = 1e11;

/// What condensing a problem of a given size costs (estimates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CondensingCost {
    /// Decision variables `n = blocks x inputs`.
    pub variables: usize,
    /// Bytes of the matrices held at once.
    pub bytes: f64,
    /// Floating-point operations.
    pub flops: f64,
}

impl CondensingCost {
    /// The cost of a horizon `horizon` with `blocks` move blocks for a
    /// model of `nx` states, `nu` inputs and `ny` outputs and `p`
    /// parameters.
    ///
    /// ```
    /// use kestrel_mpc::CondensingCost;
    /// let c = CondensingCost::of(5, 4, 3, 9, 100_000, 100_000);
    /// assert_eq!(c.variables, 400_000);
    /// assert!(c.bytes > 1e12); // terabytes: refused by MpcProblem::build
    /// ```
    pub fn of(nx: usize, nu: usize, ny: usize, p: usize, horizon: usize, blocks: usize) -> Self {
        let n = blocks.saturating_mul(nu);
        let (nf, pf, nxf, nuf, nyf) = (n as f64, p as f64, nx as f64, nu as f64, ny as f64);
        let steps = horizon as f64 + 1.0;
        // The predictions xz, xt; H, F, Y, G, E and their copies in the mpQP.
        let bytes = 8.0 * (steps * nxf * (nf + pf) + 6.0 * nf * nf + 6.0 * nf * pf + pf * pf);
        // Per step: A xz (nx^2 n), the outputs C xz (ny nx n) and the cost
        // terms H += Mz' Q Mz ((ny + nu) n^2 and the F, Y terms).
        let flops =
            2.0 * steps * (nxf * nxf * (nf + pf) + nyf * nxf * nf + (nyf + nuf) * nf * (nf + pf));
        CondensingCost {
            variables: n,
            bytes,
            flops,
        }
    }

    /// `Ok` when every estimate is within its limit
    /// ([`MAX_DECISION_VARIABLES`], [`MAX_CONDENSING_BYTES`],
    /// [`MAX_CONDENSING_FLOPS`]), otherwise [`MpcError::TooLarge`].
    pub fn check(&self, horizon: usize, blocks: usize) -> Result<(), MpcError> {
        if self.variables <= MAX_DECISION_VARIABLES
            && self.bytes <= MAX_CONDENSING_BYTES
            && self.flops <= MAX_CONDENSING_FLOPS
        {
            return Ok(());
        }
        Err(MpcError::TooLarge {
            what: format!(
                "horizon N = {horizon} with {blocks} move blocks ({} decision variables)",
                self.variables
            ),
            cost: format!(
                "about {} of memory and {:.0e} operations",
                human_bytes(self.bytes),
                self.flops
            ),
            limit: format!(
                "at most {MAX_DECISION_VARIABLES} decision variables, {} and {MAX_CONDENSING_FLOPS:.0e} operations",
                human_bytes(MAX_CONDENSING_BYTES)
            ),
        })
    }
}

/// `bytes` as `1.5 GB`, `320 MB`, `12 kB`.
pub fn human_bytes(bytes: f64) -> String {
    let units = [(1e12, "TB"), (1e9, "GB"), (1e6, "MB"), (1e3, "kB")];
    for (scale, unit) in units {
        if bytes >= scale {
            return format!("{:.1} {unit}", bytes / scale);
        }
    }
    format!("{bytes:.0} bytes")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_and_larger_problems_pass_long_unblocked_horizons_do_not() {
        // Thesis N = 2 (one block), larger N = 10 (4 blocks), 5 states, 9 parameters.
        assert!(CondensingCost::of(5, 4, 3, 9, 2, 1).check(2, 1).is_ok());
        assert!(CondensingCost::of(5, 4, 3, 9, 10, 4).check(10, 4).is_ok());
        assert!(
            CondensingCost::of(8, 4, 3, 12, 50, 50)
                .check(50, 50)
                .is_ok()
        );
        for n in [2_000, 100_000] {
            let e = CondensingCost::of(5, 4, 3, 9, n, n)
                .check(n, n)
                .unwrap_err();
            assert!(matches!(e, MpcError::TooLarge { .. }), "{e}");
            assert!(e.to_string().contains("decision variables"), "{e}");
        }
        // A long horizon in few blocks is cheap.
        assert!(
            CondensingCost::of(5, 4, 3, 9, 10_000, 4)
                .check(10_000, 4)
                .is_ok()
        );
        assert_eq!(human_bytes(2.5e9), "2.5 GB");
    }
}
