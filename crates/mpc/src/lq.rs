//! The LQ terminal weight (7.18)-(7.19).

use crate::error::MpcError;
use nalgebra::DMatrix;

/// The Riccati solution `S` of
/// `A'SA - S - A'SB (Q2 + B'SB)^-1 B'SA + C'Q1C = 0` (errata for (7.18)),
/// from `kestrel_kalman::dlqr` with `Q = C'Q1C`, `R = Q2`. With the stage
/// cost `1/2 (y'Q1y + u'Q2u)` the cost-to-go is `1/2 x'Sx`, so `S` is the
/// terminal state weight of (7.19).
pub(crate) fn lq_terminal_weight(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q1: &DMatrix<f64>,
    q2: &DMatrix<f64>,
) -> Result<DMatrix<f64>, MpcError> {
    let q = c.transpose() * q1 * c;
    let q = (&q + q.transpose()) * 0.5;
    kestrel_kalman::dlqr(a, b, &q, q2, None)
        .map(|l| (&l.s + l.s.transpose()) * 0.5)
        .map_err(|e| MpcError::Terminal(e.to_string()))
}
