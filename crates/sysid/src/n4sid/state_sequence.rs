//! The state-sequence regression (Van Overschee and De Moor's
//! algorithm 2) and the residual covariances behind `K`.

use crate::data::IoData;
use crate::linalg::{lstsq, spectral_radius};
use nalgebra::{DMatrix, DVector};

/// Consecutive pairs of the estimated state sequence of [`n4sid`](crate::n4sid()) with
/// the input and output at the first of each pair: column `t` of `x`,
/// `xn`, `u`, `y` holds `x_t`, `x_{t+1}`, `u_t`, `y_t`.
pub(super) struct StateSequence {
    pub(super) x: DMatrix<f64>,
    pub(super) xn: DMatrix<f64>,
    pub(super) u: DMatrix<f64>,
    pub(super) y: DMatrix<f64>,
}

/// System matrices of a state-sequence regression.
pub(super) struct Abcd {
    pub(super) a: DMatrix<f64>,
    pub(super) b: DMatrix<f64>,
    pub(super) c: DMatrix<f64>,
    pub(super) d: DMatrix<f64>,
}

impl StateSequence {
    /// The pairs of `xs`, whose column `c0 + c` is the state at sample
    /// `c + past` of the experiment of `data` whose columns `spans`
    /// start at `c0`.
    pub(super) fn new(
        xs: &DMatrix<f64>,
        spans: &[(usize, usize)],
        data: &IoData,
        past: usize,
    ) -> Self {
        let mut cols: [Vec<DVector<f64>>; 4] = Default::default();
        for (e, &(c0, j)) in data.experiments().iter().zip(spans) {
            for c in 0..j.saturating_sub(1) {
                cols[0].push(xs.column(c0 + c).into_owned());
                cols[1].push(xs.column(c0 + c + 1).into_owned());
                cols[2].push(e.u.row(c + past).transpose());
                cols[3].push(e.y.row(c + past).transpose());
            }
        }
        let [x, xn, u, y] = cols.map(|c| DMatrix::from_columns(&c));
        StateSequence { x, xn, u, y }
    }

    /// `[x+; y] = [A B; C D] [x; u]` by least squares (`D = 0` without
    /// feed-through). An unstable `A` is replaced by `a_stable` with `B`
    /// refitted for it.
    pub(super) fn regress(&self, a_stable: &DMatrix<f64>, feedthrough: bool) -> Abcd {
        let StateSequence { x, xn, u, y } = self;
        let (n, nu, ny) = (x.nrows(), u.nrows(), y.nrows());
        let mut xu = x.clone().resize_vertically(n + nu, 0.0);
        xu.rows_mut(n, nu).copy_from(u);
        let ab = lstsq(&xu.transpose(), &xn.transpose()).transpose();
        let (mut a, mut b) = (
            ab.columns(0, n).into_owned(),
            ab.columns(n, nu).into_owned(),
        );
        if spectral_radius(&a) >= 1.0 {
            a = a_stable.clone();
            b = lstsq(&u.transpose(), &(xn - &a * x).transpose()).transpose();
        }
        let (c, d) = if feedthrough {
            let cd = lstsq(&xu.transpose(), &y.transpose()).transpose();
            (
                cd.columns(0, n).into_owned(),
                cd.columns(n, nu).into_owned(),
            )
        } else {
            (
                lstsq(&x.transpose(), &y.transpose()).transpose(),
                DMatrix::zeros(ny, nu),
            )
        };
        Abcd { a, b, c, d }
    }

    /// The covariances `Q`, `S`, `R` of the state and output residuals
    /// of the sequence under the given matrices.
    pub(super) fn residual_covariances(
        &self,
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        c: &DMatrix<f64>,
        d: &DMatrix<f64>,
    ) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
        let w = &self.xn - a * &self.x - b * &self.u;
        let v = &self.y - c * &self.x - d * &self.u;
        let nn = v.ncols().max(1) as f64;
        (
            &w * w.transpose() / nn,
            &w * v.transpose() / nn,
            &v * v.transpose() / nn,
        )
    }
}
