//! The fit measure every table reports (a leaf module: the validation
//! tables and the ARX baseline both use it).

use nalgebra::DMatrix;

/// The fit (4.11) in percent per output column, pooled over experiments:
/// `100 (1 - |y - yhat| / |y - mean(y)|)` with the mean over all samples.
pub fn fit_percent(y: &[DMatrix<f64>], yhat: &[DMatrix<f64>]) -> Vec<f64> {
    let ny = y.first().map(|m| m.ncols()).unwrap_or(0);
    let n: usize = y.iter().map(|m| m.nrows()).sum();
    (0..ny)
        .map(|j| {
            let mean = y.iter().map(|m| m.column(j).sum()).sum::<f64>() / n.max(1) as f64;
            let mut num = 0.0;
            let mut den = 0.0;
            for (m, h) in y.iter().zip(yhat) {
                for t in 0..m.nrows() {
                    num += (m[(t, j)] - h[(t, j)]).powi(2);
                    den += (m[(t, j)] - mean).powi(2);
                }
            }
            if den > 0.0 {
                100.0 * (1.0 - (num / den).sqrt())
            } else {
                f64::NAN
            }
        })
        .collect()
}
