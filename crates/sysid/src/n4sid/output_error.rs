//! The output-error least squares for `B`, `D` and the initial states
//! with `A`, `C` fixed.

use crate::data::IoData;
use crate::error::Result;
use crate::linalg::lstsq;
use nalgebra::{DMatrix, DVector};

/// `B`, `D` and the initial states from [`fit_bd_x0`].
pub(crate) struct BdX0 {
    pub b: DMatrix<f64>,
    pub d: DMatrix<f64>,
    pub x0: Vec<DVector<f64>>,
}

/// Least squares for `B`, `D` (optional) and one initial state per
/// experiment, with `A`, `C` fixed: the output is linear in them.
pub(crate) fn fit_bd_x0(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    data: &IoData,
    feedthrough: bool,
) -> Result<BdX0> {
    let n = a.nrows();
    let (nu, ny) = (data.nu(), data.ny());
    let ne = data.experiments().len();
    let nb = n * nu;
    let nd = if feedthrough { ny * nu } else { 0 };
    let np = nb + nd + n * ne;
    let nrows = data.n_samples() * ny;
    let mut phi = DMatrix::<f64>::zeros(nrows, np);
    let mut rhs = DVector::<f64>::zeros(nrows);
    let mut row = 0;
    for (ei, e) in data.experiments().iter().enumerate() {
        // Z_q[k] = sum_{j<k} A^{k-1-j} u_q[j]  (n x n, column p <-> b_{p,q}).
        let mut z: Vec<DMatrix<f64>> = vec![DMatrix::zeros(n, n); nu];
        let mut ak = DMatrix::<f64>::identity(n, n); // A^k
        for t in 0..e.len() {
            for q in 0..nu {
                let cz = c * &z[q]; // ny x n
                for o in 0..ny {
                    for p in 0..n {
                        phi[(row + o, q * n + p)] = cz[(o, p)];
                    }
                }
            }
            if feedthrough {
                for o in 0..ny {
                    for q in 0..nu {
                        phi[(row + o, nb + q * ny + o)] = e.u[(t, q)];
                    }
                }
            }
            let cak = c * &ak;
            for o in 0..ny {
                for p in 0..n {
                    phi[(row + o, nb + nd + ei * n + p)] = cak[(o, p)];
                }
                rhs[row + o] = e.y[(t, o)];
            }
            for q in 0..nu {
                let mut zn = a * &z[q];
                for p in 0..n {
                    zn[(p, p)] += e.u[(t, q)];
                }
                z[q] = zn;
            }
            ak = a * ak;
            row += ny;
        }
    }
    let theta = lstsq(&phi, &DMatrix::from_column_slice(nrows, 1, rhs.as_slice()));
    let mut b = DMatrix::zeros(n, nu);
    for q in 0..nu {
        for p in 0..n {
            b[(p, q)] = theta[(q * n + p, 0)];
        }
    }
    let mut d = DMatrix::zeros(ny, nu);
    if feedthrough {
        for q in 0..nu {
            for o in 0..ny {
                d[(o, q)] = theta[(nb + q * ny + o, 0)];
            }
        }
    }
    let x0 = (0..ne)
        .map(|ei| DVector::from_fn(n, |p, _| theta[(nb + nd + ei * n + p, 0)]))
        .collect();
    Ok(BdX0 { b, d, x0 })
}
