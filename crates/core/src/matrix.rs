//! Small array-backed matrices and vector kernels with const-generic sizes.
//!
//! Everything here lives on the stack (or in a `static`), never allocates
//! and never panics: sizes are checked by the type system. Vectors are plain
//! arrays `[S; N]`; the free functions ([`dot`], [`axpy`], ...) work on them.

use crate::scalar::Scalar;

/// A dense `R x C` matrix stored row-major in a nested array.
///
/// ```
/// use kestrel_core::Matrix;
/// let a = Matrix::from_rows([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]);
/// assert_eq!(a.mul_vec(&[1.0, 1.0]), [3.0, 7.0, 11.0]);
/// assert_eq!(a.tr_mul_vec(&[1.0, 0.0, 1.0]), [6.0, 8.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Matrix<S, const R: usize, const C: usize> {
    /// The entries, `data[i][j]` being row `i`, column `j`.
    pub data: [[S; C]; R],
}

impl<S: Scalar, const R: usize, const C: usize> Default for Matrix<S, R, C> {
    fn default() -> Self {
        Self::zeros()
    }
}

impl<S: Scalar, const R: usize, const C: usize> Matrix<S, R, C> {
    /// Number of rows.
    pub const ROWS: usize = R;
    /// Number of columns.
    pub const COLS: usize = C;

    /// The zero matrix.
    #[inline]
    pub const fn zeros() -> Self {
        Matrix {
            data: [[S::ZERO; C]; R],
        }
    }
    /// A matrix from its rows.
    #[inline]
    pub const fn from_rows(data: [[S; C]; R]) -> Self {
        Matrix { data }
    }
    /// A matrix whose entry `(i, j)` is `f(i, j)`.
    #[inline]
    pub fn from_fn(mut f: impl FnMut(usize, usize) -> S) -> Self {
        let mut m = Self::zeros();
        for (i, row) in m.data.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = f(i, j);
            }
        }
        m
    }
    /// Converts `f64` rows into this scalar (see [`Scalar::from_f64`]).
    #[inline]
    pub fn from_f64_rows(rows: &[[f64; C]; R]) -> Self {
        Self::from_fn(|i, j| S::from_f64(rows[i][j]))
    }
    /// Converts every entry to another scalar type via `f64`.
    #[inline]
    pub fn cast<T: Scalar>(&self) -> Matrix<T, R, C> {
        Matrix::from_fn(|i, j| T::from_f64(self.data[i][j].to_f64()))
    }
    /// Entry `(i, j)`, or `None` outside the matrix.
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> Option<S> {
        self.data.get(i).and_then(|r| r.get(j)).copied()
    }
    /// Row `i` (panics never: `None` outside).
    #[inline]
    pub fn row(&self, i: usize) -> Option<&[S; C]> {
        self.data.get(i)
    }
    /// The transpose.
    #[inline]
    pub fn transpose(&self) -> Matrix<S, C, R> {
        Matrix::from_fn(|i, j| self.data[j][i])
    }
    /// `A x`.
    #[inline]
    pub fn mul_vec(&self, x: &[S; C]) -> [S; R] {
        let mut y = [S::ZERO; R];
        self.mul_vec_into(x, &mut y);
        y
    }
    /// `y = A x`, into a caller-owned buffer.
    #[inline]
    pub fn mul_vec_into(&self, x: &[S; C], y: &mut [S; R]) {
        for (yi, row) in y.iter_mut().zip(self.data.iter()) {
            *yi = S::dot(row, x);
        }
    }
    /// `y += A x`.
    #[inline]
    pub fn mul_vec_acc(&self, x: &[S; C], y: &mut [S; R]) {
        for (yi, row) in y.iter_mut().zip(self.data.iter()) {
            *yi += S::dot(row, x);
        }
    }
    /// `A' x` (transpose product) without forming the transpose.
    #[inline]
    pub fn tr_mul_vec(&self, x: &[S; R]) -> [S; C] {
        let mut y = [S::ZERO; C];
        for (row, xi) in self.data.iter().zip(x.iter()) {
            axpy(*xi, row, &mut y);
        }
        y
    }
    /// The product `A B`.
    #[inline]
    pub fn mul_mat<const K: usize>(&self, b: &Matrix<S, C, K>) -> Matrix<S, R, K> {
        let mut out = Matrix::<S, R, K>::zeros();
        for (orow, arow) in out.data.iter_mut().zip(self.data.iter()) {
            for (aij, brow) in arow.iter().zip(b.data.iter()) {
                axpy(*aij, brow, orow);
            }
        }
        out
    }
    /// Entry-wise sum.
    #[inline]
    pub fn add(&self, other: &Self) -> Self {
        Self::from_fn(|i, j| self.data[i][j] + other.data[i][j])
    }
    /// Entry-wise difference.
    #[inline]
    pub fn sub(&self, other: &Self) -> Self {
        Self::from_fn(|i, j| self.data[i][j] - other.data[i][j])
    }
    /// Every entry times `alpha`.
    #[inline]
    pub fn scale(&self, alpha: S) -> Self {
        Self::from_fn(|i, j| alpha * self.data[i][j])
    }
    /// Whether every entry is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.data.iter().all(|r| all_finite(r))
    }
}

impl<S: Scalar, const N: usize> Matrix<S, N, N> {
    /// The identity matrix.
    #[inline]
    pub fn identity() -> Self {
        Self::from_fn(|i, j| if i == j { S::ONE } else { S::ZERO })
    }
}

/// Inner product `x' y`.
#[inline]
pub fn dot<S: Scalar, const N: usize>(x: &[S; N], y: &[S; N]) -> S {
    S::dot(x, y)
}

/// `y += alpha x`.
#[inline]
pub fn axpy<S: Scalar, const N: usize>(alpha: S, x: &[S; N], y: &mut [S; N]) {
    for (yi, xi) in y.iter_mut().zip(x.iter()) {
        *yi = yi.mul_add(alpha, *xi);
    }
}

/// `x + y`.
#[inline]
pub fn add<S: Scalar, const N: usize>(x: &[S; N], y: &[S; N]) -> [S; N] {
    let mut z = *x;
    for (zi, yi) in z.iter_mut().zip(y.iter()) {
        *zi += *yi;
    }
    z
}

/// `x - y`.
#[inline]
pub fn sub<S: Scalar, const N: usize>(x: &[S; N], y: &[S; N]) -> [S; N] {
    let mut z = *x;
    for (zi, yi) in z.iter_mut().zip(y.iter()) {
        *zi -= *yi;
    }
    z
}

/// `alpha x`.
#[inline]
pub fn scale<S: Scalar, const N: usize>(alpha: S, x: &[S; N]) -> [S; N] {
    let mut z = *x;
    for zi in z.iter_mut() {
        *zi *= alpha;
    }
    z
}

/// Clamps `x` entry-wise into `[lo, hi]`.
#[inline]
pub fn clamp<S: Scalar, const N: usize>(x: &mut [S; N], lo: &[S; N], hi: &[S; N]) {
    for ((xi, l), h) in x.iter_mut().zip(lo.iter()).zip(hi.iter()) {
        *xi = xi.clamp(*l, *h);
    }
}

/// Whether every entry of a slice is finite.
#[inline]
pub fn all_finite<S: Scalar>(x: &[S]) -> bool {
    x.iter().all(|v| v.is_finite())
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // index loops mirror the textbook reference
mod tests {
    use super::*;
    use crate::scalar::Q16;
    use proptest::prelude::*;
    use std::vec::Vec;

    /// Naive f64 reference for `A x`.
    fn ref_mul_vec(a: &[[f64; 4]; 3], x: &[f64; 4]) -> [f64; 3] {
        let mut y = [0.0; 3];
        for i in 0..3 {
            for j in 0..4 {
                y[i] += a[i][j] * x[j];
            }
        }
        y
    }

    fn arr<const N: usize>(v: &[f64]) -> [f64; N] {
        let mut a = [0.0; N];
        a.copy_from_slice(&v[..N]);
        a
    }

    fn mat34(v: &[f64]) -> [[f64; 4]; 3] {
        [arr(&v[0..4]), arr(&v[4..8]), arr(&v[8..12])]
    }

    /// Checks the kernels in scalar `S` against the f64 reference, with an
    /// absolute tolerance `tol` that reflects the format's resolution.
    fn check_kernels<S: Scalar>(av: &[f64], xv: &[f64], yv: &[f64], alpha: f64, tol: f64) {
        let a64 = mat34(av);
        let x64: [f64; 4] = arr(xv);
        let y64: [f64; 3] = arr(yv);
        let a = Matrix::<S, 3, 4>::from_f64_rows(&a64);
        // Reference computed from the *rounded* inputs, so only arithmetic error remains.
        let ar = a.cast::<f64>();
        let x: [S; 4] = core::array::from_fn(|i| S::from_f64(x64[i]));
        let xr: [f64; 4] = core::array::from_fn(|i| x[i].to_f64());
        let y: [S; 3] = core::array::from_fn(|i| S::from_f64(y64[i]));
        let yr: [f64; 3] = core::array::from_fn(|i| y[i].to_f64());

        let got = a.mul_vec(&x);
        let want = ref_mul_vec(&ar.data, &xr);
        for i in 0..3 {
            assert!((got[i].to_f64() - want[i]).abs() <= tol, "mul_vec {i}");
        }
        let mut acc = y;
        a.mul_vec_acc(&x, &mut acc);
        for i in 0..3 {
            assert!(
                (acc[i].to_f64() - (want[i] + yr[i])).abs() <= 2.0 * tol,
                "mul_vec_acc {i}"
            );
        }
        let gt = a.tr_mul_vec(&y);
        for j in 0..4 {
            let w: f64 = (0..3).map(|i| ar.data[i][j] * yr[i]).sum();
            assert!((gt[j].to_f64() - w).abs() <= 3.0 * tol, "tr_mul_vec {j}");
        }
        let t = a.transpose();
        for i in 0..3 {
            for j in 0..4 {
                assert_eq!(t.data[j][i], a.data[i][j]);
            }
        }
        let s = S::from_f64(alpha);
        let mut z = x;
        axpy(s, &a.data[0], &mut z);
        for j in 0..4 {
            let w = xr[j] + s.to_f64() * ar.data[0][j];
            assert!((z[j].to_f64() - w).abs() <= tol, "axpy {j}");
        }
        let d = dot(&x, &a.data[1]);
        let w: f64 = (0..4).map(|j| xr[j] * ar.data[1][j]).sum();
        assert!((d.to_f64() - w).abs() <= tol, "dot");
        // A (A' y) through mul_mat of the transpose equals the explicit Gram product.
        let g = a.mul_mat(&t);
        for i in 0..3 {
            for k in 0..3 {
                let w: f64 = (0..4).map(|j| ar.data[i][j] * ar.data[k][j]).sum();
                assert!((g.data[i][k].to_f64() - w).abs() <= 4.0 * tol, "mul_mat");
            }
        }
    }

    fn vals(n: usize) -> impl Strategy<Value = Vec<f64>> {
        proptest::collection::vec(-8.0f64..8.0, n)
    }

    proptest! {
        #[test]
        fn kernels_f64(a in vals(12), x in vals(4), y in vals(3), alpha in -3.0f64..3.0) {
            check_kernels::<f64>(&a, &x, &y, alpha, 1e-12);
        }
        #[test]
        fn kernels_f32(a in vals(12), x in vals(4), y in vals(3), alpha in -3.0f64..3.0) {
            check_kernels::<f32>(&a, &x, &y, alpha, 1e-4);
        }
        #[test]
        fn kernels_fixed(a in vals(12), x in vals(4), y in vals(3), alpha in -3.0f64..3.0) {
            // Products round once per dot (fixed dot uses a wide accumulator),
            // axpy rounds once per entry: a few LSBs at most.
            check_kernels::<Q16>(&a, &x, &y, alpha, 4.0 * Q16::RESOLUTION);
        }
    }

    #[test]
    fn identity_and_helpers() {
        let i3 = Matrix::<f64, 3, 3>::identity();
        assert_eq!(i3.mul_vec(&[1.0, 2.0, 3.0]), [1.0, 2.0, 3.0]);
        let m = Matrix::from_rows([[1.0, 2.0], [3.0, 4.0]]);
        assert_eq!(m.add(&m).data, m.scale(2.0).data);
        assert_eq!(m.sub(&m), Matrix::zeros());
        assert_eq!(m.get(1, 0), Some(3.0));
        assert_eq!(m.get(2, 0), None);
        assert!(m.row(5).is_none());
        assert_eq!(add(&[1.0, 2.0], &[3.0, 4.0]), [4.0, 6.0]);
        assert_eq!(sub(&[1.0, 2.0], &[3.0, 4.0]), [-2.0, -2.0]);
        assert_eq!(scale(2.0, &[1.0, 2.0]), [2.0, 4.0]);
        let mut c = [5.0, -5.0, 0.5];
        clamp(&mut c, &[0.0; 3], &[1.0; 3]);
        assert_eq!(c, [1.0, 0.0, 0.5]);
        assert!(!all_finite(&[1.0, f64::NAN]));
        assert!(!Matrix::from_rows([[f32::INFINITY]]).is_finite());
    }

    #[test]
    fn fixed_matrix_saturates() {
        let big = Matrix::<Q16, 1, 2>::from_f64_rows(&[[30000.0, 30000.0]]);
        assert_eq!(big.mul_vec(&[Q16::ONE, Q16::ONE]), [Q16::MAX]);
    }
}
