//! The floating-point operation model of kestrel-qp's solver: one add,
//! subtract, multiply or divide is one flop, a fused multiply-add two;
//! comparisons, sign flips and copies are free. Each function counts what
//! the corresponding code of `crates/qp/src/iterate.rs` does for `n`
//! variables, `k` active constraints and `m` general rows (docs/qp-certify.md
//! lists them).

/// Per solve: `L^-1 q` (an `n x n` triangle as a full product) and
/// `y_unc = -D^-1 L^-1 q`: `2 n^2 + 2 n`.
pub(super) fn preamble(n: u64) -> u64 {
    2 * n * n + 2 * n
}

/// The solution `z = L^-T y` read at the end: `2 n^2`.
pub(super) fn solution(n: u64) -> u64 {
    2 * n * n
}

/// `mu* = M^-1 (A_A y_unc - b_A)`: `k` dot products of length `n` and a
/// subtraction, forward and backward substitution and the diagonal:
/// `2 n k + 2 k^2 + k`.
pub(super) fn mustar(n: u64, k: u64) -> u64 {
    2 * n * k + 2 * k * k + k
}

/// The blocking test over `k` positions (sign products, `cur - star`, the
/// ratio): at most `4 k`.
pub(super) fn blocking(k: u64) -> u64 {
    4 * k
}

/// The dual step `mu <- mu + alpha (mu* - mu)`: `3 k`.
pub(super) fn dual_step(k: u64) -> u64 {
    3 * k
}

/// Removing position `p` of `k`: the rank-one update of the `t = k - 1 - p`
/// trailing rows, `7 t + 2 t (t - 1)`.
pub(super) fn remove(k: u64, p: u64) -> u64 {
    let t = k.saturating_sub(1 + p);
    7 * t + 2 * t * t.saturating_sub(1)
}

/// The primal point `y = y_unc - D^-1 A_A' mu`: `3 n k`.
pub(super) fn primal(n: u64, k: u64) -> u64 {
    3 * n * k
}

/// The most-violated scan over `inactive` constraints: a dot product of
/// length `n` and two subtractions each, `(2 n + 2) inactive`.
pub(super) fn scan(n: u64, inactive: u64) -> u64 {
    (2 * n + 2) * inactive
}

/// Adding a constraint to `k` active: `D^-1 a`, its squared norm, `k` dot
/// products, the forward solve and the new pivot: `3 n + 2 n k + k^2 + 3 k
/// + 1`.
pub(super) fn add(n: u64, k: u64) -> u64 {
    3 * n + 2 * n * k + k * k + 3 * k + 1
}

/// The singular step with `k` active (the last dependent): the null vector
/// `L^-T e_k`, the ratios, the multiplier update: `k (k - 1) + 4 (k - 1) +
/// 3 k` (the removal is [`remove`]).
pub(super) fn singular(k: u64) -> u64 {
    k * k.saturating_sub(1) + 4 * k.saturating_sub(1) + 3 * k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_cases() {
        assert_eq!(remove(1, 0), 0);
        assert_eq!(remove(3, 0), 7 * 2 + 2 * 2);
        assert_eq!(add(4, 0), 13);
        assert_eq!(preamble(4), 40);
        assert_eq!(singular(2), 2 + 4 + 6);
        assert_eq!(
            mustar(4, 2) + blocking(2) + dual_step(2),
            16 + 8 + 2 + 8 + 6
        );
        assert_eq!(primal(4, 1) + scan(4, 7) + solution(4), 12 + 70 + 32);
    }
}
