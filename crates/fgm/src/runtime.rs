//! The run-time solver: `no_std`, allocation-free, panic-free, generic over
//! [`Scalar`].
//!
//! Everything the iterations need is folded offline (see
//! [`FgmDesign`](crate::FgmDesign)) into the scaled variables `v = D^-1 z`:
//!
//! - `M = I - D H D / L` (the gradient step of the scaled problem),
//! - `c(theta) = K theta + k0 = -D (F' theta + f) / L` (the linear term),
//! - `lo(theta) = Lo theta + lo0`, `hi(theta) = Hi theta + hi0` (the box),
//! - the momentum `beta_i` (one constant or a table).
//!
//! A solve computes `c`, `lo`, `hi` once, takes the start point (cold: the
//! box centre; warm: the given point clamped into the box), takes one projected gradient step (the *initial step* on which the
//! certificate rests) and then exactly `iterations` fast-gradient
//! iterations, each one `M y`, an add, a clamp and the momentum update:
//!
//! ```text
//! z_0 = clamp(M s + c)                  s = centre or clamp(start), y_0 = z_0
//! z_{i+1} = clamp(M y_i + c)
//! y_{i+1} = z_{i+1} + beta_i (z_{i+1} - z_i)
//! ```
//!
//! The output is `z = D v` in the problem's own units. Two front ends share
//! the kernel [`solve_view`]: [`FgmTables`] (const dimensions, plain
//! arrays, can be written as a `static` for the firmware) and, with `std`,
//! [`FgmData`](crate::FgmData) (run-time dimensions, for the CLI).

use kestrel_core::{Error, Matrix, Scalar, check_len};

/// Borrowed, flattened solver tables (row-major matrices as slices).
///
/// `n` decision variables, `p` parameters. Build one with
/// [`FgmTables::view`] or [`FgmData::view`](crate::FgmData::view).
#[derive(Clone, Copy, Debug)]
pub struct FgmView<'a, S> {
    /// Number of decision variables.
    pub n: usize,
    /// Number of parameters.
    pub p: usize,
    /// `M = I - D H D / L`, `n x n` row-major.
    pub m: &'a [S],
    /// `K = -D F' / L`, `n x p` row-major.
    pub k_theta: &'a [S],
    /// `k0 = -D f / L`, `n`.
    pub k0: &'a [S],
    /// Scaled lower bound map, `n x p` row-major.
    pub lo_theta: &'a [S],
    /// Scaled lower bound offset, `n`.
    pub lo0: &'a [S],
    /// Scaled upper bound map, `n x p` row-major.
    pub hi_theta: &'a [S],
    /// Scaled upper bound offset, `n`.
    pub hi0: &'a [S],
    /// The diagonal scaling `z = D v`, `n`.
    pub d: &'a [S],
    /// Its inverse `v = D^-1 z` (for warm starts), `n`.
    pub d_inv: &'a [S],
    /// Momentum: iteration `i` uses `betas[min(i, len - 1)]`; one entry
    /// means constant momentum. Must not be empty.
    pub betas: &'a [S],
}

impl<'a, S> FgmView<'a, S> {
    /// The ten arrays in the order of the fields: `m`, `k_theta`, `k0`,
    /// `lo_theta`, `lo0`, `hi_theta`, `hi0`, `d`, `d_inv`, `betas` (the
    /// order of an exported table and of a firmware's flat table).
    ///
    /// ```
    /// use kestrel_fgm::FgmTables;
    /// use kestrel_core::Matrix;
    ///
    /// let t: FgmTables<f64, 1, 1, 1> = FgmTables {
    ///     m: Matrix::from_rows([[0.5]]),
    ///     k_theta: Matrix::from_rows([[-1.0]]),
    ///     k0: [0.0],
    ///     lo_theta: Matrix::from_rows([[0.0]]),
    ///     lo0: [-1.0],
    ///     hi_theta: Matrix::from_rows([[0.0]]),
    ///     hi0: [1.0],
    ///     d: [1.0],
    ///     d_inv: [1.0],
    ///     betas: [0.0],
    ///     iterations: 10,
    ///     warm_iterations: 5,
    ///     shift: 1,
    /// };
    /// let flat: Vec<f64> = t.view().parts().concat();
    /// assert_eq!(flat, [0.5, -1.0, 0.0, 0.0, -1.0, 0.0, 1.0, 1.0, 1.0, 0.0]);
    /// ```
    pub fn parts(&self) -> [&'a [S]; 10] {
        [
            self.m,
            self.k_theta,
            self.k0,
            self.lo_theta,
            self.lo0,
            self.hi_theta,
            self.hi0,
            self.d,
            self.d_inv,
            self.betas,
        ]
    }
}

/// Caller-owned scratch vectors of a solve, each of length `n`.
#[derive(Debug)]
pub struct WorkspaceMut<'a, S> {
    /// Lower bound at the current parameter.
    pub lo: &'a mut [S],
    /// Upper bound at the current parameter.
    pub hi: &'a mut [S],
    /// Linear term `c(theta)`.
    pub c: &'a mut [S],
    /// Current iterate `z_i` (scaled).
    pub z: &'a mut [S],
    /// Extrapolated point `y_i` (scaled).
    pub y: &'a mut [S],
    /// Scratch for `M y + c`.
    pub w: &'a mut [S],
}

/// Where a solve starts.
#[derive(Clone, Copy, Debug)]
pub enum Start<'a, S> {
    /// Cold start from the centre of the box `(lo(theta) + hi(theta)) / 2`
    /// (the point the cold-start certificate is for: every optimum is
    /// within half a width of it in each variable).
    Cold,
    /// Warm start from a point in the problem's units (e.g. the previous
    /// solution, possibly shifted); clamped into the current box first.
    Warm(&'a [S]),
}

fn affine_into<S: Scalar>(a: &[S], b: &[S], theta: &[S], out: &mut [S]) {
    let p = theta.len();
    if p == 0 {
        out.copy_from_slice(b);
        return;
    }
    for ((o, row), bi) in out.iter_mut().zip(a.chunks_exact(p)).zip(b.iter()) {
        *o = S::dot(row, theta) + *bi;
    }
}

/// The fast-gradient kernel shared by every front end.
///
/// Runs the initial projected gradient step and then `iterations`
/// iterations from `start`, for the parameter `theta`, and writes the
/// solution in the problem's units into `out`. Time is deterministic: the
/// same operations for every `theta`.
///
/// # Errors
/// [`Error::DimensionMismatch`] for a table, workspace or vector of the
/// wrong length, [`Error::InvalidArgument`] for an empty momentum table,
/// [`Error::NonFinite`] for a NaN or infinite parameter or start point,
/// [`Error::Infeasible`] if the box is empty at `theta` (`lo > hi`).
pub fn solve_view<S: Scalar>(
    t: &FgmView<'_, S>,
    theta: &[S],
    start: Start<'_, S>,
    iterations: usize,
    ws: WorkspaceMut<'_, S>,
    out: &mut [S],
) -> Result<(), Error> {
    let (n, p) = (t.n, t.p);
    check_len(t.m, n * n)?;
    check_len(t.k_theta, n * p)?;
    check_len(t.lo_theta, n * p)?;
    check_len(t.hi_theta, n * p)?;
    for v in [t.k0, t.lo0, t.hi0, t.d, t.d_inv] {
        check_len(v, n)?;
    }
    if t.betas.is_empty() {
        return Err(Error::InvalidArgument("betas: the momentum table is empty"));
    }
    check_len(theta, p)?;
    check_len(out, n)?;
    let WorkspaceMut { lo, hi, c, z, y, w } = ws;
    for v in [&*lo, &*hi, &*c, &*z, &*y, &*w] {
        check_len(v, n)?;
    }
    if !kestrel_core::all_finite(theta) {
        return Err(Error::NonFinite);
    }

    affine_into(t.lo_theta, t.lo0, theta, lo);
    affine_into(t.hi_theta, t.hi0, theta, hi);
    if lo.iter().zip(hi.iter()).any(|(l, h)| l > h) {
        return Err(Error::Infeasible);
    }
    affine_into(t.k_theta, t.k0, theta, c);

    // Start point s in scaled units, clamped into the box.
    match start {
        Start::Cold => centre_into(lo, hi, y),
        Start::Warm(z0) => {
            check_len(z0, n)?;
            if !kestrel_core::all_finite(z0) {
                return Err(Error::NonFinite);
            }
            for ((yi, zi), di) in y.iter_mut().zip(z0.iter()).zip(t.d_inv.iter()) {
                *yi = *zi * *di;
            }
        }
    }
    clamp_slice(y, lo, hi);

    // Initial projected gradient step: z_0 = clamp(M s + c), y_0 = z_0.
    gradient_step(t.m, y, c, lo, hi, w);
    z.copy_from_slice(w);
    y.copy_from_slice(w);

    let last = t.betas.len() - 1;
    for i in 0..iterations {
        let beta = match t.betas.get(i) {
            Some(b) => *b,
            None => t.betas.get(last).copied().unwrap_or(S::ZERO),
        };
        // w = z_{i+1} = clamp(M y_i + c)
        gradient_step(t.m, y, c, lo, hi, w);
        // y_{i+1} = z_{i+1} + beta (z_{i+1} - z_i); z <- z_{i+1}
        for ((yi, zi), wi) in y.iter_mut().zip(z.iter_mut()).zip(w.iter()) {
            *yi = *wi + beta * (*wi - *zi);
            *zi = *wi;
        }
    }
    for ((o, zi), di) in out.iter_mut().zip(z.iter()).zip(t.d.iter()) {
        *o = *zi * *di;
    }
    Ok(())
}

/// `w = clamp(M y + c, lo, hi)`.
#[inline]
fn gradient_step<S: Scalar>(m: &[S], y: &[S], c: &[S], lo: &[S], hi: &[S], w: &mut [S]) {
    let n = y.len();
    if n == 0 {
        return;
    }
    for ((((wi, row), ci), l), h) in w
        .iter_mut()
        .zip(m.chunks_exact(n))
        .zip(c.iter())
        .zip(lo.iter())
        .zip(hi.iter())
    {
        *wi = (S::dot(row, y) + *ci).clamp(*l, *h);
    }
}

/// `out = A theta + b` on arrays (same operation order as `affine_into`).
#[inline(always)]
fn affine_fixed<S: Scalar, const N: usize, const P: usize>(
    a: &Matrix<S, N, P>,
    b: &[S; N],
    theta: &[S; P],
    out: &mut [S; N],
) {
    for ((o, row), bi) in out.iter_mut().zip(a.data.iter()).zip(b.iter()) {
        *o = S::dot(row, theta) + *bi;
    }
}

/// `w = clamp(M y + c, lo, hi)` on arrays: `M y` as `M' y`
/// ([`Scalar::tr_mat_vec`], the same per-entry order as `gradient_step`'s
/// dot, so bit-identical for the symmetric `M` the design writes).
#[inline(always)]
fn gradient_step_fixed<S: Scalar, const N: usize>(
    m: &Matrix<S, N, N>,
    y: &[S; N],
    c: &[S; N],
    lo: &[S; N],
    hi: &[S; N],
    w: &mut [S; N],
) {
    S::tr_mat_vec(&m.data, y, w);
    for (((wi, ci), l), h) in w.iter_mut().zip(c.iter()).zip(lo.iter()).zip(hi.iter()) {
        *wi = (*wi + *ci).clamp(*l, *h);
    }
}

/// `y = (lo + hi) / 2`, the cold start.
#[inline]
fn centre_into<S: Scalar>(lo: &[S], hi: &[S], y: &mut [S]) {
    let half = S::from_f64(0.5);
    for ((yi, l), h) in y.iter_mut().zip(lo.iter()).zip(hi.iter()) {
        *yi = (*l + *h) * half;
    }
}

#[inline]
fn clamp_slice<S: Scalar>(x: &mut [S], lo: &[S], hi: &[S]) {
    for ((xi, l), h) in x.iter_mut().zip(lo.iter()).zip(hi.iter()) {
        *xi = xi.clamp(*l, *h);
    }
}

/// Solver tables with const dimensions: `N` decision variables, `P`
/// parameters, `T` momentum entries (`T = 1`: constant momentum).
///
/// Plain arrays with public fields, so that [`export_rust`](crate::export_rust)
/// can write them as a `static` for the firmware. Build them at design time
/// with [`FgmDesign::tables`](crate::FgmDesign::tables).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FgmTables<S, const N: usize, const P: usize, const T: usize> {
    /// `M = I - D H D / L`, symmetric (the design writes it exactly
    /// symmetric; the fixed-size kernel reads its rows as columns, i.e.
    /// computes `M' y`).
    pub m: Matrix<S, N, N>,
    /// `K = -D F' / L`.
    pub k_theta: Matrix<S, N, P>,
    /// `k0 = -D f / L`.
    pub k0: [S; N],
    /// Scaled lower bound map.
    pub lo_theta: Matrix<S, N, P>,
    /// Scaled lower bound offset.
    pub lo0: [S; N],
    /// Scaled upper bound map.
    pub hi_theta: Matrix<S, N, P>,
    /// Scaled upper bound offset.
    pub hi0: [S; N],
    /// The scaling `z = D v`.
    pub d: [S; N],
    /// The inverse scaling `v = D^-1 z`.
    pub d_inv: [S; N],
    /// Momentum table (`T = 1`: constant momentum).
    pub betas: [S; T],
    /// The certified number of iterations for a cold start.
    pub iterations: usize,
    /// The certified number of iterations for a warm start (see
    /// [`Certificate::warm`](crate::Certificate)).
    pub warm_iterations: usize,
    /// Entries to shift the previous solution by for a warm start (the
    /// size of the first input block; 0 = reuse it unshifted).
    pub shift: usize,
}

/// Caller-owned workspace of a solve with `N` variables; it also keeps the
/// previous solution for warm starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FgmWorkspace<S, const N: usize> {
    lo: [S; N],
    hi: [S; N],
    c: [S; N],
    z: [S; N],
    y: [S; N],
    w: [S; N],
    prev: [S; N],
    has_prev: bool,
}

impl<S: Scalar, const N: usize> Default for FgmWorkspace<S, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<S: Scalar, const N: usize> FgmWorkspace<S, N> {
    /// A zeroed workspace without a previous solution.
    pub const fn new() -> Self {
        FgmWorkspace {
            lo: [S::ZERO; N],
            hi: [S::ZERO; N],
            c: [S::ZERO; N],
            z: [S::ZERO; N],
            y: [S::ZERO; N],
            w: [S::ZERO; N],
            prev: [S::ZERO; N],
            has_prev: false,
        }
    }
    /// The last solution, if any.
    pub fn previous(&self) -> Option<&[S; N]> {
        self.has_prev.then_some(&self.prev)
    }
    /// Forgets the previous solution (the next warm solve starts cold).
    pub fn reset(&mut self) {
        self.has_prev = false;
    }
}

/// Shifts `prev` by `shift` entries into `out` and repeats its last
/// `shift` entries (the standard MPC warm start); `shift = 0` copies.
pub fn shift_into<S: Scalar>(prev: &[S], shift: usize, out: &mut [S]) -> Result<(), Error> {
    let n = prev.len();
    check_len(out, n)?;
    if shift >= n {
        out.copy_from_slice(prev);
        return Ok(());
    }
    let (head, tail) = out.split_at_mut(n - shift);
    head.copy_from_slice(prev.get(shift..).unwrap_or(&[]));
    tail.copy_from_slice(prev.get(n - shift..).unwrap_or(&[]));
    Ok(())
}

impl<S: Scalar, const N: usize, const P: usize, const T: usize> FgmTables<S, N, P, T> {
    /// The flattened view the kernel works on.
    pub fn view(&self) -> FgmView<'_, S> {
        FgmView {
            n: N,
            p: P,
            m: self.m.data.as_flattened(),
            k_theta: self.k_theta.data.as_flattened(),
            k0: &self.k0,
            lo_theta: self.lo_theta.data.as_flattened(),
            lo0: &self.lo0,
            hi_theta: self.hi_theta.data.as_flattened(),
            hi0: &self.hi0,
            d: &self.d,
            d_inv: &self.d_inv,
            betas: &self.betas,
        }
    }

    /// Runs `iterations` iterations from `start` (see [`solve_view`]) and
    /// stores the result as the previous solution in `ws`.
    ///
    /// This is the fixed-size kernel: the same operations in the same order
    /// as [`solve_view`] (so the results are bit-identical), on arrays of
    /// known length, which the compiler unrolls without bounds checks.
    ///
    /// # Errors
    /// As [`solve_view`].
    pub fn solve_with(
        &self,
        theta: &[S; P],
        start: Start<'_, S>,
        iterations: usize,
        ws: &mut FgmWorkspace<S, N>,
    ) -> Result<[S; N], Error> {
        if T == 0 {
            return Err(Error::InvalidArgument("betas: the momentum table is empty"));
        }
        if !kestrel_core::all_finite(theta) {
            return Err(Error::NonFinite);
        }
        let FgmWorkspace {
            lo, hi, c, z, y, w, ..
        } = ws;
        affine_fixed(&self.lo_theta, &self.lo0, theta, lo);
        affine_fixed(&self.hi_theta, &self.hi0, theta, hi);
        if lo.iter().zip(hi.iter()).any(|(l, h)| l > h) {
            return Err(Error::Infeasible);
        }
        affine_fixed(&self.k_theta, &self.k0, theta, c);
        match start {
            Start::Cold => centre_into(lo, hi, y),
            Start::Warm(z0) => {
                check_len(z0, N)?;
                if !kestrel_core::all_finite(z0) {
                    return Err(Error::NonFinite);
                }
                for ((yi, zi), di) in y.iter_mut().zip(z0.iter()).zip(self.d_inv.iter()) {
                    *yi = *zi * *di;
                }
            }
        }
        clamp_slice(y, lo, hi);
        gradient_step_fixed(&self.m, y, c, lo, hi, w);
        *z = *w;
        *y = *w;
        let last = self.betas.last().copied().unwrap_or(S::ZERO);
        for i in 0..iterations {
            let beta = self.betas.get(i).copied().unwrap_or(last);
            gradient_step_fixed(&self.m, y, c, lo, hi, w);
            for ((yi, zi), wi) in y.iter_mut().zip(z.iter_mut()).zip(w.iter()) {
                *yi = *wi + beta * (*wi - *zi);
                *zi = *wi;
            }
        }
        let mut out = [S::ZERO; N];
        for ((o, zi), di) in out.iter_mut().zip(z.iter()).zip(self.d.iter()) {
            *o = *zi * *di;
        }
        ws.prev = out;
        ws.has_prev = true;
        Ok(out)
    }

    /// Cold start with the certified number of iterations.
    ///
    /// # Errors
    /// As [`solve_view`].
    pub fn solve(&self, theta: &[S; P], ws: &mut FgmWorkspace<S, N>) -> Result<[S; N], Error> {
        self.solve_with(theta, Start::Cold, self.iterations, ws)
    }

    /// Warm start from the previous solution in `ws`, shifted by
    /// [`FgmTables::shift`], with the certified warm-start iteration count;
    /// falls back to a certified cold start when there is none.
    ///
    /// # Errors
    /// As [`solve_view`].
    pub fn solve_warm(&self, theta: &[S; P], ws: &mut FgmWorkspace<S, N>) -> Result<[S; N], Error> {
        match ws.previous() {
            None => self.solve(theta, ws),
            Some(prev) => {
                let mut start = [S::ZERO; N];
                shift_into(prev, self.shift, &mut start)?;
                self.solve_with(theta, Start::Warm(&start), self.warm_iterations, ws)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_repeats_last_block() {
        let mut out = [0.0; 5];
        shift_into(&[1.0, 2.0, 3.0, 4.0, 5.0], 2, &mut out).unwrap();
        assert_eq!(out, [3.0, 4.0, 5.0, 4.0, 5.0]);
        shift_into(&[1.0, 2.0, 3.0, 4.0, 5.0], 0, &mut out).unwrap();
        assert_eq!(out, [1.0, 2.0, 3.0, 4.0, 5.0]);
        assert!(shift_into(&[1.0, 2.0], 1, &mut out).is_err());
    }

    /// One variable, one parameter: z in [theta - 1, theta + 1], cost
    /// 1/2 z^2 (M = 0 with L = 1), so the answer is clamp(0).
    fn tiny() -> FgmTables<f64, 1, 1, 1> {
        FgmTables {
            m: Matrix::from_rows([[0.0]]),
            k_theta: Matrix::from_rows([[0.0]]),
            k0: [0.0],
            lo_theta: Matrix::from_rows([[1.0]]),
            lo0: [-1.0],
            hi_theta: Matrix::from_rows([[1.0]]),
            hi0: [1.0],
            d: [1.0],
            d_inv: [1.0],
            betas: [0.5],
            iterations: 3,
            warm_iterations: 1,
            shift: 0,
        }
    }

    #[test]
    fn solves_and_reports_bad_input() {
        let t = tiny();
        let mut ws = FgmWorkspace::new();
        assert_eq!(t.solve(&[0.5], &mut ws), Ok([0.0]));
        assert_eq!(t.solve(&[3.0], &mut ws), Ok([2.0]));
        assert_eq!(ws.previous(), Some(&[2.0]));
        assert_eq!(t.solve_warm(&[2.5], &mut ws), Ok([1.5]));
        assert_eq!(t.solve(&[f64::NAN], &mut ws), Err(Error::NonFinite));
        let mut empty = t;
        empty.lo0 = [2.0];
        empty.hi0 = [1.0];
        assert_eq!(empty.solve(&[0.0], &mut ws), Err(Error::Infeasible));
        let v = t.view();
        // One cold or warm solve of a view with fresh workspace buffers.
        let run = |view: &FgmView<'_, f64>, theta: &[f64], start: Start<'_, f64>| {
            let mut buf = [[0.0; 1]; 6];
            let [lo, hi, c, z, y, w] = &mut buf;
            let mut out = [0.0];
            solve_view(
                view,
                theta,
                start,
                1,
                WorkspaceMut { lo, hi, c, z, y, w },
                &mut out,
            )
        };
        let bad = FgmView { betas: &[], ..v };
        assert!(matches!(
            run(&bad, &[0.0], Start::Cold),
            Err(Error::InvalidArgument(_))
        ));
        let short = FgmView { m: &[], ..v };
        assert_eq!(
            run(&short, &[0.0], Start::Cold),
            Err(Error::DimensionMismatch {
                expected: 1,
                found: 0
            })
        );
        assert_eq!(
            run(&v, &[0.0, 1.0], Start::Cold),
            Err(Error::DimensionMismatch {
                expected: 1,
                found: 2
            })
        );
        assert_eq!(
            run(&v, &[0.0], Start::Warm(&[f64::INFINITY])),
            Err(Error::NonFinite)
        );
    }
}
