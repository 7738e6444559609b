//! The critical region of an active set: the KKT laws of the multipliers
//! and the optimiser, and the half-spaces where they hold.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::lp::LpWorkspace;
use crate::mpqp::prepare::Prepared;
use crate::mpqp::region::{Origin, RegionData};
use nalgebra::{DMatrix, DVector};

impl Prepared {
    /// Computes the region of an active set (reduced indices, sorted);
    /// `None` if LICQ fails or the region is lower-dimensional or empty.
    pub(super) fn region(&self, act: &[usize], lp: &mut LpWorkspace) -> Option<RegionData> {
        let (n, p, m) = (self.n, self.p, self.m);
        let k = act.len();
        if k > n {
            return None;
        }
        let mut lam_t = DMatrix::zeros(k, p);
        let mut lam_c = DVector::zeros(k);
        let mut kz = -self.hinv_ft.clone();
        let mut kzc = -self.hinv_f.clone();
        if k > 0 {
            let mut ga = DMatrix::zeros(k, n);
            let mut hga = DMatrix::zeros(n, k);
            for (r, &i) in act.iter().enumerate() {
                ga.row_mut(r).copy_from(&self.g.row(i));
                hga.column_mut(r).copy_from(&self.hinv_gt.column(i));
            }
            let mm = &ga * &hga;
            let mmax = (0..k).map(|i| mm[(i, i)]).fold(0.0, f64::max);
            let chol = mm.cholesky()?;
            let minp = (0..k)
                .map(|i| chol.l()[(i, i)].powi(2))
                .fold(f64::INFINITY, f64::min);
            if minp <= 1e-10 * mmax.max(1e-300) {
                return None; // LICQ violated
            }
            let mut rt = &ga * &self.hinv_ft; // k x p
            let mut rc = &ga * &self.hinv_f;
            for (r, &i) in act.iter().enumerate() {
                for j in 0..p {
                    rt[(r, j)] += self.e[(i, j)];
                }
                rc[r] += self.w[i];
            }
            lam_t = -chol.solve(&rt);
            lam_c = -chol.solve(&rc);
            kz -= &hga * &lam_t;
            kzc -= &hga * &lam_c;
        }
        // Half-spaces.
        // Raw half-spaces, one flat row-major array (no allocation per row).
        let nraw = k + (m - k) + self.param_b.len();
        let mut raw_a: Vec<f64> = Vec::with_capacity(nraw * p);
        let mut raw: Vec<(f64, Origin)> = Vec::with_capacity(nraw);
        for (r, &j) in act.iter().enumerate() {
            raw_a.extend((0..p).map(|c| -lam_t[(r, c)]));
            raw.push((lam_c[r], Origin::Dual(j)));
        }
        let gk = &self.g * &kz; // m x p
        let gkc = &self.g * &kzc;
        for i in 0..m {
            if act.binary_search(&i).is_ok() {
                continue;
            }
            raw_a.extend((0..p).map(|c| gk[(i, c)] - self.e[(i, c)]));
            raw.push((self.w[i] - gkc[i], Origin::Primal(i)));
        }
        for i in 0..self.param_b.len() {
            raw_a.extend(self.param_a.row(i).iter().copied());
            raw.push((self.param_b[i], Origin::Param));
        }
        let mut hs_a: Vec<f64> = Vec::with_capacity(raw.len() * p);
        let mut hs_b: Vec<f64> = Vec::with_capacity(raw.len());
        let mut origins: Vec<Vec<Origin>> = Vec::with_capacity(raw.len());
        let mut a = vec![0.0; p];
        for (ra, &(b, o)) in raw_a.chunks_exact(p).zip(&raw) {
            let nrm = ra.iter().map(|v| v * v).sum::<f64>().sqrt();
            if nrm <= 1e-10 {
                if b < -1e-9 * self.scale {
                    return None; // empty
                }
                continue; // always satisfied
            }
            for (x, v) in a.iter_mut().zip(ra) {
                *x = v / nrm;
            }
            let b = b / nrm;
            let cnt = hs_b.len();
            let mut merged = false;
            for q in 0..cnt {
                let aq = &hs_a[q * p..(q + 1) * p];
                if (hs_b[q] - b).abs() <= 1e-10 * self.scale
                    && aq.iter().zip(&a).all(|(x, y)| (x - y).abs() <= 1e-10)
                {
                    origins[q].push(o);
                    merged = true;
                    break;
                }
            }
            if !merged {
                hs_a.extend_from_slice(&a);
                hs_b.push(b);
                origins.push(vec![o]);
            }
        }
        let mut buf = (Vec::new(), Vec::new());
        let mut lps = 1;
        let (center, radius) = self.chebyshev(&hs_a, &hs_b, None, lp, &mut buf)?;
        if radius <= self.radius_tol {
            return None;
        }
        // Facets: half-spaces with a full-dimensional face.
        let facets = self.facets(&hs_a, &hs_b, &origins, &center, act, lp, &mut buf, &mut lps);
        Some(RegionData {
            active: act.to_vec(),
            hs_a,
            hs_b,
            origins,
            facets,
            kz,
            kzc,
            center,
            radius,
            lps,
        })
    }
}
