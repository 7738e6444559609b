//! Eigenvalues of a real square matrix with an iteration limit (feature
//! `std`): balancing, reduction to Hessenberg form by stabilised
//! elimination, and the Francis double-shift QR iteration with exceptional
//! shifts and a limit of 30 iterations per eigenvalue (EISPACK
//! `balanc`/`elmhes`/`hqr`, as in Numerical Recipes, 2nd ed., sections
//! 11.5-11.6); should that fail, nalgebra's Schur decomposition with an
//! iteration limit and a few perturbed retries.
//!
//! Why not nalgebra's `complex_eigenvalues`: it runs its Francis
//! iteration without an iteration limit and deflates only when a
//! subdiagonal entry falls below machine epsilon times its diagonal
//! neighbours; while solving the Riccati equation of a Kalman filter with
//! several identical, decoupled actuator and disturbance modes a
//! subdiagonal entry stalled just above that and the iteration cycled for
//! ever (kestrel-kalman's `repeated_decoupled_modes_do_not_hang`). Its `Schur::try_new` has a limit but always
//! accumulates the Schur vectors (a third of a Riccati solve's time at
//! n = 20). This routine needs no eigenvectors, always returns, and says
//! [`Error::NotConverged`] when it cannot deliver.
//!
//! ```
//! use kestrel_core::eig::{eigenvalues, spectral_radius};
//! use nalgebra::DMatrix;
//! // Rotation by 0.3 rad scaled by 0.9: eigenvalues 0.9 e^(+-0.3 i).
//! let (c, s) = (0.9 * 0.3f64.cos(), 0.9 * 0.3f64.sin());
//! let m = DMatrix::from_row_slice(2, 2, &[c, -s, s, c]);
//! let e = eigenvalues(&m).unwrap();
//! assert!(e.iter().all(|z| (z.norm() - 0.9).abs() < 1e-14));
//! assert!((spectral_radius(&m).unwrap() - 0.9).abs() < 1e-14);
//! // Bad input is an error value, not a panic or a hang.
//! assert!(eigenvalues(&DMatrix::from_element(2, 2, f64::NAN)).is_err());
//! assert!(eigenvalues(&DMatrix::zeros(2, 3)).is_err());
//! ```

use std::{vec, vec::Vec};

use crate::error::Error;
use nalgebra::{Complex, DMatrix, DVector, Schur};

/// Eigenvalues of the real square matrix `m`, in no particular order
/// (complex pairs adjacent).
///
/// Errors: [`Error::DimensionMismatch`] when `m` is not square (`expected`
/// is the number of rows), [`Error::NonFinite`] for NaN or infinite
/// entries, [`Error::NotConverged`] when neither the QR iteration (30
/// iterations per eigenvalue) nor the fallbacks (nalgebra's Schur
/// decomposition with `30 n + 30` sweeps on `m`, on `m'`, with a deflation
/// threshold of `64 eps`, and on an orthogonal similarity `P m P`)
/// converge.
pub fn eigenvalues(m: &DMatrix<f64>) -> Result<DVector<Complex<f64>>, Error> {
    let n = m.nrows();
    if m.ncols() != n {
        return Err(Error::DimensionMismatch {
            expected: n,
            found: m.ncols(),
        });
    }
    if n == 0 {
        return Ok(DVector::zeros(0));
    }
    if !m.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite);
    }
    if let Some(e) = hqr_eigenvalues(m) {
        return Ok(e);
    }
    let limit = 30 * n + 30;
    let attempt =
        |x: DMatrix<f64>, eps: f64| Schur::try_new(x, eps, limit).map(|s| s.complex_eigenvalues());
    for eps in [f64::EPSILON, 64.0 * f64::EPSILON] {
        if let Some(e) = attempt(m.clone(), eps) {
            return Ok(e);
        }
        if let Some(e) = attempt(m.transpose(), eps) {
            return Ok(e);
        }
    }
    let v = DVector::from_fn(n, |i, _| 1.0 / (i as f64 + 1.0).sqrt());
    let p = DMatrix::identity(n, n) - &v * v.transpose() * (2.0 / v.norm_squared());
    attempt(&p * m * &p, 64.0 * f64::EPSILON).ok_or(Error::NotConverged)
}

/// Spectral radius `max |lambda_i|` of the real square matrix `m` (0 for
/// an empty matrix); the errors of [`eigenvalues`].
pub fn spectral_radius(m: &DMatrix<f64>) -> Result<f64, Error> {
    Ok(eigenvalues(m)?.iter().map(|z| z.norm()).fold(0.0, f64::max))
}

/// A 1-indexed dense square matrix (row-major), so the classical
/// algorithms read as published.
struct Mat1 {
    n: usize,
    data: Vec<f64>,
}

impl Mat1 {
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> f64 {
        self.data[i * (self.n + 1) + j]
    }
    #[inline(always)]
    fn set(&mut self, i: usize, j: usize, v: f64) {
        let n = self.n;
        self.data[i * (n + 1) + j] = v;
    }
    #[inline(always)]
    fn sub(&mut self, i: usize, j: usize, v: f64) {
        let n = self.n;
        self.data[i * (n + 1) + j] -= v;
    }
}

/// Eigenvalues of `m` (any order), or `None` when the QR iteration needs
/// more than 30 iterations for one eigenvalue or the matrix is not finite.
fn hqr_eigenvalues(m: &DMatrix<f64>) -> Option<DVector<Complex<f64>>> {
    let n = m.nrows();
    if m.ncols() != n || !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut a = Mat1 {
        n,
        data: vec![0.0; (n + 1) * (n + 1)],
    };
    for i in 1..=n {
        for j in 1..=n {
            a.set(i, j, m[(i - 1, j - 1)]);
        }
    }
    balance(&mut a);
    hessenberg(&mut a);
    let (wr, wi) = hqr(&mut a)?;
    Some(DVector::from_fn(n, |i, _| {
        Complex::new(wr[i + 1], wi[i + 1])
    }))
}

/// Diagonal similarity by powers of 2 so that rows and columns have
/// comparable norms (`balanc`).
fn balance(a: &mut Mat1) {
    const RADIX: f64 = 2.0;
    let n = a.n;
    let sqrdx = RADIX * RADIX;
    let mut done = false;
    let mut sweeps = 0;
    while !done && sweeps < 100 {
        done = true;
        sweeps += 1;
        for i in 1..=n {
            let (mut r, mut c) = (0.0, 0.0);
            for j in 1..=n {
                if j != i {
                    c += a.at(j, i).abs();
                    r += a.at(i, j).abs();
                }
            }
            if c != 0.0 && r != 0.0 {
                let mut g = r / RADIX;
                let mut f = 1.0;
                let s = c + r;
                while c < g {
                    f *= RADIX;
                    c *= sqrdx;
                }
                g = r * RADIX;
                while c > g {
                    f /= RADIX;
                    c /= sqrdx;
                }
                if (c + r) / f < 0.95 * s {
                    done = false;
                    let g = 1.0 / f;
                    for j in 1..=n {
                        let v = a.at(i, j) * g;
                        a.set(i, j, v);
                    }
                    for j in 1..=n {
                        let v = a.at(j, i) * f;
                        a.set(j, i, v);
                    }
                }
            }
        }
    }
}

/// Reduction to upper Hessenberg form by elimination with pivoting
/// (`elmhes`); the entries below the subdiagonal are zeroed.
fn hessenberg(a: &mut Mat1) {
    let n = a.n;
    for m in 2..n {
        let mut x = 0.0f64;
        let mut i = m;
        for j in m..=n {
            if a.at(j, m - 1).abs() > x.abs() {
                x = a.at(j, m - 1);
                i = j;
            }
        }
        if i != m {
            for j in (m - 1)..=n {
                let (u, v) = (a.at(i, j), a.at(m, j));
                a.set(i, j, v);
                a.set(m, j, u);
            }
            for j in 1..=n {
                let (u, v) = (a.at(j, i), a.at(j, m));
                a.set(j, i, v);
                a.set(j, m, u);
            }
        }
        if x != 0.0 {
            for i in (m + 1)..=n {
                let mut y = a.at(i, m - 1);
                if y != 0.0 {
                    y /= x;
                    a.set(i, m - 1, y);
                    for j in m..=n {
                        let v = y * a.at(m, j);
                        a.sub(i, j, v);
                    }
                    for j in 1..=n {
                        let v = y * a.at(j, i);
                        a.sub(j, m, -v);
                    }
                }
            }
        }
    }
    for i in 3..=n {
        for j in 1..=(i - 2) {
            a.set(i, j, 0.0);
        }
    }
}

#[inline(always)]
fn sign(a: f64, b: f64) -> f64 {
    if b >= 0.0 { a.abs() } else { -a.abs() }
}

/// Francis double-shift QR on an upper Hessenberg matrix (`hqr`); returns
/// the real and imaginary parts (1-indexed), `None` after 30 iterations on
/// one eigenvalue.
#[allow(clippy::many_single_char_names)]
fn hqr(a: &mut Mat1) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = a.n;
    let mut wr = vec![0.0; n + 1];
    let mut wi = vec![0.0; n + 1];
    let mut anorm = 0.0;
    for i in 1..=n {
        for j in i.saturating_sub(1).max(1)..=n {
            anorm += a.at(i, j).abs();
        }
    }
    let mut nn = n;
    let mut t = 0.0;
    let (mut p, mut q, mut r): (f64, f64, f64);
    let (mut x, mut y, mut z, mut w): (f64, f64, f64, f64);
    while nn >= 1 {
        let mut its = 0;
        loop {
            let mut l = nn;
            while l >= 2 {
                let mut s = a.at(l - 1, l - 1).abs() + a.at(l, l).abs();
                if s == 0.0 {
                    s = anorm;
                }
                if a.at(l, l - 1).abs() + s == s {
                    a.set(l, l - 1, 0.0);
                    break;
                }
                l -= 1;
            }
            x = a.at(nn, nn);
            if l == nn {
                wr[nn] = x + t;
                wi[nn] = 0.0;
                nn -= 1;
            } else {
                y = a.at(nn - 1, nn - 1);
                w = a.at(nn, nn - 1) * a.at(nn - 1, nn);
                if l == nn - 1 {
                    p = 0.5 * (y - x);
                    q = p * p + w;
                    z = q.abs().sqrt();
                    x += t;
                    if q >= 0.0 {
                        z = p + sign(z, p);
                        wr[nn - 1] = x + z;
                        wr[nn] = x + z;
                        if z != 0.0 {
                            wr[nn] = x - w / z;
                        }
                        wi[nn - 1] = 0.0;
                        wi[nn] = 0.0;
                    } else {
                        wr[nn - 1] = x + p;
                        wr[nn] = x + p;
                        wi[nn - 1] = -z;
                        wi[nn] = z;
                    }
                    nn -= 2;
                } else {
                    if its == 30 {
                        return None;
                    }
                    if its == 10 || its == 20 {
                        // Exceptional shift.
                        t += x;
                        for i in 1..=nn {
                            a.sub(i, i, x);
                        }
                        let s = a.at(nn, nn - 1).abs() + a.at(nn - 1, nn - 2).abs();
                        x = 0.75 * s;
                        y = x;
                        w = -0.4375 * s * s;
                    }
                    its += 1;
                    let mut m = nn - 2;
                    loop {
                        z = a.at(m, m);
                        r = x - z;
                        let s0 = y - z;
                        p = (r * s0 - w) / a.at(m + 1, m) + a.at(m, m + 1);
                        q = a.at(m + 1, m + 1) - z - r - s0;
                        r = a.at(m + 2, m + 1);
                        let s = p.abs() + q.abs() + r.abs();
                        p /= s;
                        q /= s;
                        r /= s;
                        if m == l {
                            break;
                        }
                        let u = a.at(m, m - 1).abs() * (q.abs() + r.abs());
                        let v = p.abs()
                            * (a.at(m - 1, m - 1).abs() + z.abs() + a.at(m + 1, m + 1).abs());
                        if u + v == v {
                            break;
                        }
                        m -= 1;
                    }
                    for i in (m + 2)..=nn {
                        a.set(i, i - 2, 0.0);
                        if i != m + 2 {
                            a.set(i, i - 3, 0.0);
                        }
                    }
                    let mut k = m;
                    while k < nn {
                        if k != m {
                            p = a.at(k, k - 1);
                            q = a.at(k + 1, k - 1);
                            r = 0.0;
                            if k != nn - 1 {
                                r = a.at(k + 2, k - 1);
                            }
                            x = p.abs() + q.abs() + r.abs();
                            if x != 0.0 {
                                p /= x;
                                q /= x;
                                r /= x;
                            }
                        }
                        let s = sign((p * p + q * q + r * r).sqrt(), p);
                        if s != 0.0 {
                            if k == m {
                                if l != m {
                                    let v = -a.at(k, k - 1);
                                    a.set(k, k - 1, v);
                                }
                            } else {
                                a.set(k, k - 1, -s * x);
                            }
                            p += s;
                            x = p / s;
                            y = q / s;
                            z = r / s;
                            q /= p;
                            r /= p;
                            // Rows k, k+1 (and k+2) from column k on, as
                            // slices (contiguous, no per-entry index checks).
                            let w1 = n + 1;
                            let (row_k, rest) = a.data[k * w1..].split_at_mut(w1);
                            let (row_k1, rest) = rest.split_at_mut(w1);
                            let (row_k, row_k1) = (&mut row_k[k..=nn], &mut row_k1[k..=nn]);
                            if k != nn - 1 {
                                let row_k2 = &mut rest[k..=nn];
                                for ((u, v), w) in row_k
                                    .iter_mut()
                                    .zip(row_k1.iter_mut())
                                    .zip(row_k2.iter_mut())
                                {
                                    let pj = *u + q * *v + r * *w;
                                    *w -= pj * z;
                                    *v -= pj * y;
                                    *u -= pj * x;
                                }
                            } else {
                                for (u, v) in row_k.iter_mut().zip(row_k1.iter_mut()) {
                                    let pj = *u + q * *v;
                                    *v -= pj * y;
                                    *u -= pj * x;
                                }
                            }
                            let mmin = if nn < k + 3 { nn } else { k + 3 };
                            for i in l..=mmin {
                                p = x * a.at(i, k) + y * a.at(i, k + 1);
                                if k != nn - 1 {
                                    p += z * a.at(i, k + 2);
                                    a.sub(i, k + 2, p * r);
                                }
                                a.sub(i, k + 1, p * q);
                                a.sub(i, k, p);
                            }
                        }
                        k += 1;
                    }
                }
            }
            if nn < 2 || l + 1 >= nn {
                break;
            }
        }
    }
    if !(wr.iter().all(|v| v.is_finite()) && wi.iter().all(|v| v.is_finite())) {
        return None;
    }
    Some((wr, wi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_distr::StandardNormal;
    use rand_xoshiro::SplitMix64;
    use std::vec::Vec;

    /// Random test matrices: standard normal entries (`rand_distr`) from
    /// the workspace's seeded generator (`rand_xoshiro::SplitMix64`).
    struct Rng(SplitMix64);
    impl Rng {
        fn new(seed: u64) -> Self {
            Rng(SplitMix64::seed_from_u64(seed))
        }
        fn matrix(&mut self, r: usize, c: usize) -> DMatrix<f64> {
            DMatrix::from_fn(r, c, |_, _| self.0.sample(StandardNormal))
        }
    }

    /// Sorted (by real, then imaginary part) copy.
    fn sorted(v: &DVector<Complex<f64>>) -> Vec<Complex<f64>> {
        let mut s: Vec<_> = v.iter().copied().collect();
        s.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        s
    }

    /// Every eigenvalue of `e` is an eigenvalue of `m`: the smallest
    /// singular value of `m - z I` is tiny. Independent of any QR code.
    fn check_is_spectrum(m: &DMatrix<f64>, e: &DVector<Complex<f64>>, tol: f64) {
        let n = m.nrows();
        assert_eq!(e.len(), n);
        let norm = m.norm().max(1e-300);
        for z in e.iter() {
            let shifted =
                m.map(|v| Complex::new(v, 0.0)) - DMatrix::<Complex<f64>>::identity(n, n) * *z;
            let smin = shifted.singular_values().min();
            assert!(
                smin <= tol * norm,
                "{z}: smallest singular value {smin:.2e}"
            );
        }
        // Trace and (for small n) determinant agree.
        let tr: Complex<f64> = e.iter().sum();
        assert!((tr.re - m.trace()).abs() <= 1e-10 * norm * n as f64);
        assert!(tr.im.abs() <= 1e-10 * norm * n as f64);
    }

    #[test]
    fn random_matrices_match_nalgebra() {
        let mut rng = Rng::new(3);
        for n in [1usize, 2, 3, 4, 5, 8, 13, 20, 33, 60] {
            for _ in 0..3 {
                let m = rng.matrix(n, n);
                let e = hqr_eigenvalues(&m).expect("converges");
                check_is_spectrum(&m, &e, 1e-10);
                let reference = m.complex_eigenvalues();
                for (a, b) in sorted(&e).iter().zip(sorted(&reference).iter()) {
                    assert!(
                        (a - b).norm() < 1e-9 * (1.0 + b.norm()),
                        "n={n}: {a} vs {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn known_spectra() {
        // Rotation by 0.3 rad scaled by 0.9: 0.9 e^{+-0.3 i}.
        let (c, s) = (0.9 * 0.3f64.cos(), 0.9 * 0.3f64.sin());
        let m = DMatrix::from_row_slice(2, 2, &[c, -s, s, c]);
        let e = sorted(&hqr_eigenvalues(&m).unwrap());
        assert!((e[0] - Complex::new(c, -s)).norm() < 1e-15);
        assert!((e[1] - Complex::new(c, s)).norm() < 1e-15);
        // Companion matrix of (z - 1)(z - 2)(z - 3)(z + 0.5) = z^4 - 5.5 z^3 + 8 z^2 - 0.5 z - 3.
        let m = DMatrix::from_row_slice(
            4,
            4,
            &[
                5.5, -8.0, 0.5, 3.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
        );
        let e = sorted(&hqr_eigenvalues(&m).unwrap());
        for (z, want) in e.iter().zip([-0.5, 1.0, 2.0, 3.0]) {
            assert!(
                (z - Complex::new(want, 0.0)).norm() < 1e-12,
                "{z} vs {want}"
            );
        }
        // Zero, identity, Jordan block, badly scaled (balancing), empty.
        assert!(
            hqr_eigenvalues(&DMatrix::zeros(3, 3))
                .unwrap()
                .iter()
                .all(|z| z.norm() == 0.0)
        );
        let e = hqr_eigenvalues(&DMatrix::identity(5, 5)).unwrap();
        assert!(
            e.iter()
                .all(|z| (z - Complex::new(1.0, 0.0)).norm() < 1e-15)
        );
        let j = DMatrix::from_row_slice(3, 3, &[0.5, 1.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.5]);
        let e = hqr_eigenvalues(&j).unwrap();
        assert!(e.iter().all(|z| (z - Complex::new(0.5, 0.0)).norm() < 1e-5));
        let d = DMatrix::from_diagonal(&DVector::from_vec(vec![1e-8, 1.0, 1e8]));
        let mut rng = Rng::new(9);
        let p = rng.matrix(3, 3) + DMatrix::identity(3, 3) * 3.0;
        let m = &p * &d * p.clone().try_inverse().unwrap();
        let e = sorted(&hqr_eigenvalues(&m).unwrap());
        assert!((e[2].re / 1e8 - 1.0).abs() < 1e-9 && (e[1].re - 1.0).abs() < 1e-6);
        assert_eq!(hqr_eigenvalues(&DMatrix::zeros(0, 0)).unwrap().len(), 0);
        assert!(hqr_eigenvalues(&DMatrix::from_element(2, 2, f64::NAN)).is_none());
    }

    /// The Kalman closed loop `A - L C` of the 11-state tricopter rate
    /// model with three identical motor modes and three identical gust
    /// modes (kestrel-kalman's `repeated_decoupled_modes_do_not_hang`,
    /// where nalgebra's `complex_eigenvalues` cycled for ever on a matrix
    /// met during the Riccati solve).
    fn repeated_modes_closed_loop() -> DMatrix<f64> {
        #[rustfmt::skip]
        let m = DMatrix::from_row_slice(11, 11, &[
            -2.8633804556317655e-1, 1.6780493515217189e-3, -1.283822008947332e-2, 0e0, 2.622542971220504e-3, -2.622542971220504e-3, 0e0, 0e0, 5e-1, 0e0, 0e0,
            1.3263154579968841e-3, 1.2186841855893071e-1, -1.7533814111183283e-2, -2.6885640103174943e-3, 1.3458896803515722e-3, 1.3458896803515722e-3, 6.089812349437849e-2, 4.791315708005133e-4, 0e0, 4.444444444444444e-1, 0e0,
            -8.126655069194997e-4, -1.4005456798416988e-3, 5.917578672913253e-1, -1.2098538046428721e-4, 6.056503561582075e-5, 6.056503561582075e-5, -4.2818993081984874e-1, -3.36889385719111e-3, 0e0, 0e0, 2.5e-1,
            -3.0256417369372466e-13, 9.693291617642226e-11, 1.0988785910791312e-11, 6.703200460356393e-1, 0e0, 0e0, 0e0, 0e0, 0e0, 0e0, 0e0,
            -1.7269876113244148e-10, -4.8122736190322155e-11, -7.867328188160575e-12, 0e0, 6.703200460356393e-1, 0e0, 0e0, 0e0, 0e0, 0e0, 0e0,
            1.7300168715351125e-10, -4.89261055464416e-11, -3.1345996068784238e-12, 0e0, 0e0, 6.703200460356393e-1, 0e0, 0e0, 0e0, 0e0, 0e0,
            6.851413780463555e-10, -2.621353961555216e-9, 3.137358512068586e-8, 0e0, 0e0, 0e0, 8.652396208065133e-1, 1.274249904114953e-2, 0e0, 0e0, 0e0,
            -1.3743911577004037e-8, 6.5378182564164e-8, -1.0413828608828006e-6, 0e0, 0e0, 0e0, -1.1468249137034572e1, 3.300546610782333e-1, 0e0, 0e0, 0e0,
            -9.548105776432777e-1, 1.8333879212180208e-3, -1.203776714684374e-2, 0e0, 0e0, 0e0, 0e0, 0e0, 9.607894391523232e-1, 0e0, 0e0,
            1.6298250316675437e-3, -5.706963065583737e-1, -1.579831432694928e-2, 0e0, 0e0, 0e0, 0e0, 0e0, 0e0, 9.607894391523232e-1, 0e0,
            -1.5090999901132894e-3, -2.2267702998726925e-3, -2.607020749229814e-1, 0e0, 0e0, 0e0, 0e0, 0e0, 0e0, 0e0, 9.607894391523232e-1,
        ]);
        m
    }

    #[test]
    fn repeated_decoupled_modes_converge() {
        let m = repeated_modes_closed_loop();
        let e = eigenvalues(&m).expect("converges");
        check_is_spectrum(&m, &e, 1e-8);
        let rho = spectral_radius(&m).unwrap();
        assert!(rho < 1.0 && rho > 0.5, "{rho}");
        // The repeated modes: a similarity with a random orthogonal matrix
        // mixes the decoupled blocks and the spectrum stays the same.
        let mut rng = Rng::new(11);
        let q = rng.matrix(11, 11).qr().q();
        let mq = q.transpose() * &m * &q;
        let eq = eigenvalues(&mq).expect("converges");
        for (a, b) in sorted(&e).iter().zip(sorted(&eq).iter()) {
            assert!((a - b).norm() < 1e-6, "{a} vs {b}");
        }
    }

    #[test]
    fn bad_input_is_an_error_value() {
        assert_eq!(
            eigenvalues(&DMatrix::zeros(2, 3)),
            Err(Error::DimensionMismatch {
                expected: 2,
                found: 3
            })
        );
        let mut m = DMatrix::identity(3, 3);
        m[(1, 2)] = f64::INFINITY;
        assert_eq!(eigenvalues(&m), Err(Error::NonFinite));
        m[(1, 2)] = f64::NAN;
        assert_eq!(spectral_radius(&m), Err(Error::NonFinite));
        assert_eq!(eigenvalues(&DMatrix::zeros(0, 0)).unwrap().len(), 0);
        assert_eq!(spectral_radius(&DMatrix::zeros(0, 0)), Ok(0.0));
    }

    #[test]
    fn fallback_agrees_with_the_qr_iteration() {
        // The Schur fallback path on its own gives the same spectrum.
        let mut rng = Rng::new(5);
        for n in [2usize, 7, 15] {
            let m = rng.matrix(n, n);
            let fast = eigenvalues(&m).unwrap();
            let schur = Schur::try_new(m.clone(), f64::EPSILON, 30 * n + 30)
                .unwrap()
                .complex_eigenvalues();
            for (a, b) in sorted(&fast).iter().zip(sorted(&schur).iter()) {
                assert!((a - b).norm() < 1e-9 * (1.0 + b.norm()), "{a} vs {b}");
            }
        }
    }
}
