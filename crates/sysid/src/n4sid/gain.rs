//! The noise model's gain kept stabilising.

use crate::linalg;
use nalgebra::DMatrix;

/// Shrinks `K` until `A - K C` is stable (spectral radius below 0.999).
pub(crate) fn stabilise_k(a: &DMatrix<f64>, c: &DMatrix<f64>, mut k: DMatrix<f64>) -> DMatrix<f64> {
    for _ in 0..60 {
        if linalg::spectral_radius(&(a - &k * c)) < 0.999 {
            return k;
        }
        k *= 0.85;
    }
    DMatrix::zeros(k.nrows(), k.ncols())
}
