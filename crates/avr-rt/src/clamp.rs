//! Clamping without a panic path: `Ord::clamp` asserts `lo <= hi`, which
//! links the panic machinery into the firmware wherever the bounds are not
//! constants (table entries, configured limits).

/// `v` limited to `[lo, hi]`; equal to `v.clamp(lo, hi)` when `lo <= hi`,
/// and `hi` or below (never a panic) when the bounds are crossed.
#[inline(always)]
pub(crate) fn clamp<T: Ord>(v: T, lo: T, hi: T) -> T {
    v.max(lo).min(hi)
}

#[cfg(test)]
mod tests {
    use super::clamp;

    #[test]
    fn equals_ord_clamp_and_never_panics() {
        for lo in -4i32..4 {
            for hi in -4i32..4 {
                for v in -6i32..6 {
                    let c = clamp(v, lo, hi);
                    if lo <= hi {
                        assert_eq!(c, v.clamp(lo, hi));
                    } else {
                        assert!(c <= hi);
                    }
                }
            }
        }
    }
}
