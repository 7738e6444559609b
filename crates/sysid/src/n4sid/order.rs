//! The model order suggested by the singular values.

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
