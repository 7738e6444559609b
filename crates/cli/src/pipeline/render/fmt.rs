//! Number formats and series shared by the sections.

use crate::report::table::fmt_sig;

pub fn f3(v: f64) -> String {
    fmt_sig(v, 3)
}

pub fn f4(v: f64) -> String {
    fmt_sig(v, 4)
}

/// `a / b / c` with 3 significant digits.
pub fn j3(v: &[f64]) -> String {
    v.iter().map(|x| f3(*x)).collect::<Vec<_>>().join(" / ")
}

pub fn series_t(t: &[f64], v: impl Iterator<Item = f64>) -> Vec<(f64, f64)> {
    t.iter().copied().zip(v).collect()
}
