//! The floating-point operation model of kestrel-qp's solver (the code of
//! `crates/qp/src/iterate.rs`: iterations in `z` with `H^-1` and `w_j =
//! H^-1 g_j` from the set-up, the singular step with its rounding floor). One add, subtract,
//! multiply or divide is one flop (a multiplication by a side's `+-1`
//! included), a multiply-add two; comparisons, negations and copies are
//! free: every arithmetic operator the solver's code executes, as a
//! counting scalar type measures it (tests/certify.rs). `n`
//! variables, `k` active constraints; a "row" is a general row of `G`
//! (its products cost `2 n`), a bound's are free (an entry of `H^-1`,
//! `w_j` or `z`). docs/qp-certify.md lists the model.

/// Per solve: `z_unc = -H^-1 q`, `2 n^2`.
pub(super) fn preamble(n: u64) -> u64 {
    2 * n * n
}

/// `mu* = M^-1 rhs` with the forward solve kept for the first `f`
/// positions: forward `k^2 - f^2`, diagonal `k`, backward `k (k - 1)`:
/// `2 k^2 - f^2`.
pub(super) fn mustar(k: u64, f: u64) -> u64 {
    let f = f.min(k);
    2 * k * k - f * f
}

/// The blocking test: `star` of each of the `free` non-equality positions,
/// and `cur`, `cur - star` and the ratio of each of `blocking` blocking
/// ones: `free + 3 blocking`.
pub(super) fn blocking(free: u64, blocking: u64) -> u64 {
    free + 3 * blocking
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

/// The primal point `z = z_unc - sum_p w_p mu_p`: `2 n k`.
pub(super) fn primal(n: u64, k: u64) -> u64 {
    2 * n * k
}

/// The most-violated scan: `g_j'z` of each inactive row (`2 n`) and three
/// subtractions per inactive constraint (both differences, then the
/// larger again).
pub(super) fn scan(n: u64, inactive_rows: u64, inactive: u64) -> u64 {
    2 * n * inactive_rows + 3 * inactive
}

/// Adding a constraint to `k` active of which `rows_active` are rows: the
/// new row of `M` (`2 n` per entry between two rows, its diagonal `2 n`
/// for a row), the forward solve `k^2 + 3 k`, the pivot test 1, the
/// right-hand side `g_j' z_unc - b` (`2 n + 1` for a row, 1 for a bound).
pub(super) fn add(n: u64, k: u64, row: bool, rows_active: u64) -> u64 {
    let products = if row { 2 * n * (rows_active + 2) } else { 0 };
    products + k * k + 3 * k + 2
}

/// The singular step with `k` active (the last dependent): the null vector
/// `L^-T e_k` (`k (k - 1)`), its rounding floor `dual_tol * max |p|` (1),
/// the rate of each of the `free` non-equality positions before the last
/// (2) and the ratio of each of the `blocking` ones with a negative rate
/// (2), the multiplier update `3 k` (the removal is [`remove`]).
pub(super) fn singular(k: u64, free: u64, blocking: u64) -> u64 {
    k * k.saturating_sub(1) + 1 + 2 * free + 2 * blocking + 3 * k
}
