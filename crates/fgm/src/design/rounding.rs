//! Rounding analysis: magnitude bounds of the scaled intermediates and a
//! rigorous bound on the error of a solve in `f32` or fixed point (a
//! worst-case rounding analysis folded into the inexact accelerated
//! gradient bound of Schmidt, Le Roux and Bach, 2011).

use super::{Certificate, FgmDesign, MomentumScheme, RoundingBound};
use crate::precond::Spectrum;
use kestrel_core::Scalar;
use nalgebra::{DMatrix, DVector};

impl FgmDesign {
    /// How far the box tables of a solve in `S` are shrunk inwards so
    /// that every iterate is feasible despite rounding; `None` for an
    /// exact scalar (`f64`).
    pub(super) fn box_shrink<S: Scalar>(&self) -> Option<DVector<f64>> {
        let model = RoundModel::of::<S>();
        (!model.is_exact()).then(|| self.bound_rounding(&model))
    }

    /// Magnitude bounds of the scaled quantities over the box and the
    /// parameter box.
    pub(super) fn intermediate_bounds(&self, beta: f64) -> Intermediates {
        let (n, p) = (self.n(), self.problem.p());
        let th = DVector::from_fn(p, |j, _| {
            self.problem.theta_lb[j]
                .abs()
                .max(self.problem.theta_ub[j].abs())
        });
        let mag = |a0: &DVector<f64>, a: &DMatrix<f64>| -> DVector<f64> {
            DVector::from_fn(n, |i, _| a0[i].abs() + a.row(i).abs().dot(&th.transpose()))
        };
        let blo = mag(&self.lo0, &self.lo_theta);
        let bhi = mag(&self.hi0, &self.hi_theta);
        let bv = blo.zip_map(&bhi, f64::max);
        let by = &bv * (1.0 + 2.0 * beta);
        let bc = mag(&self.k0, &self.k_theta);
        let m = self.m().abs();
        let bw = &m * &by + &bc;
        let peak = by.max().max(bw.max()).max(bv.max());
        Intermediates {
            th,
            bv,
            by,
            bc,
            bw,
            peak,
        }
    }

    /// Per-variable inward shrink that covers the rounding of the bounds.
    fn bound_rounding(&self, r: &RoundModel) -> DVector<f64> {
        let ib = self.intermediate_bounds(self.constant_beta());
        let n = self.n();
        let p = self.problem.p();
        let dth = ib.th.map(|t| r.u * t + r.a);
        DVector::from_fn(n, |i, _| {
            let mut worst: f64 = 0.0;
            for (a0, a) in [(&self.lo0, &self.lo_theta), (&self.hi0, &self.hi_theta)] {
                let abs_a = a.row(i).abs().transpose();
                let s = abs_a.dot(&ib.th);
                let e = (r.u * s + r.a * ib.th.sum()) // stored entries
                    + abs_a.dot(&dth) // rounded theta
                    + r.gamma(p) * s + r.a // dot
                    + r.u * a0[i].abs() + r.a // stored offset
                    + r.u * (s + a0[i].abs()) + r.a; // the add
                worst = worst.max(e);
            }
            // Twice: once to make the computed box lie inside the true one.
            2.0 * worst
        })
    }

    /// A rigorous bound on the error of solving in scalar `S` with the
    /// constant-momentum scheme after `cert.iterations` iterations.
    /// `None` for the table scheme or `mu = 0` (no bound is derived there).
    pub fn rounding_bound<S: Scalar>(&self, cert: &Certificate) -> Option<RoundingBound> {
        if cert.scheme != MomentumScheme::Constant || self.spectrum.mu <= 0.0 {
            return None;
        }
        let r = RoundModel::of::<S>();
        let (n, p) = (self.n(), self.problem.p());
        let Spectrum { l, mu } = self.spectrum;
        let beta = self.constant_beta();
        let ib = self.intermediate_bounds(beta);
        let m = self.m().abs();
        let dth = ib.th.map(|t| r.u * t + r.a);
        // sigma: error of w = M y + c, per component.
        let sigma = DVector::from_fn(n, |i, _| {
            let my = m.row(i).transpose().dot(&ib.by);
            let stored_m = r.u * my + r.a * ib.by.sum();
            let dot_m = r.gamma(n) * my + r.a;
            let add = r.u * ib.bw[i];
            let kabs = self.k_theta.row(i).abs().transpose();
            let kt = kabs.dot(&ib.th);
            let c_err = (r.u * kt + r.a * ib.th.sum())
                + kabs.dot(&dth)
                + r.gamma(p) * kt
                + r.a
                + r.u * self.k0[i].abs()
                + r.a
                + r.u * ib.bc[i]
                + r.a;
            stored_m + dot_m + add + c_err
        });
        // rho: error of y = z + beta (z - z_prev), per component.
        let rho = ib.bv.map(|b| {
            let diff = 2.0 * b;
            (r.u * beta + r.a) * diff
                + r.u * diff * beta
                + (r.u * beta * diff + r.a)
                + r.u * 3.0 * b
                + r.a
        });
        let e = l * (rho.norm() + sigma.norm());
        let shrink = self.bound_rounding(&r);
        let diam = self.diameter_sq.sqrt();
        // The computed centre start is off the centre of the (shrunk) box
        // by the rounding of the bounds (half the shrink) and of
        // (lo + hi) / 2; sqrt(e'(L I - H)e) is a seminorm, so
        // sqrt(2 Delta_s) <= sqrt(2 Delta) + sqrt(L - mu) |offset|.
        let offset = DVector::from_fn(n, |i, _| 0.5 * shrink[i] + r.u * 2.0 * ib.bv[i] + r.a);
        let delta_start = (self.delta().sqrt() + (0.5 * (l - mu)).sqrt() * offset.norm()).powi(2);
        let delta_hat = delta_start + e * diam;
        let q = 1.0 - (mu / l).sqrt();
        let k = cert.iterations;
        let geo: f64 = (0..k).map(|j| q.powf(j as f64 / 2.0)).sum();
        let root = (2.0 * delta_hat * q.powi(k as i32)).sqrt() + (2.0 / mu).sqrt() * e * geo;
        let shrink_dist = (&shrink * 2.0).norm();
        let grad = l * (ib.bv.norm() + ib.bc.norm());
        let box_cost = grad * shrink_dist + 0.5 * l * shrink_dist * shrink_dist;
        // Output z = D v: stored d, the product.
        let zmax = &self.d.component_mul(&ib.bv);
        let out_err = DVector::from_fn(n, |i, _| {
            (r.u * self.d[i] + r.a) * ib.bv[i] + r.u * zmax[i] + r.a
        })
        .norm();
        let hz = crate::precond::spectrum(&self.problem.h).ok()?;
        if hz.mu <= 0.0 {
            return None;
        }
        let gz = grad / self.d.min(); // |grad_z| = |D^-1 grad_v|
        let cost_v = root * root + box_cost;
        let cost_bound = cost_v + gz * out_err + 0.5 * hz.l * out_err * out_err;
        let distance_bound =
            (2.0 * cost_v / hz.mu).sqrt() + (2.0 * cert.eps / hz.mu).sqrt() + out_err;
        Some(RoundingBound {
            scalar: r.name,
            gradient_error: e,
            box_shrink: shrink.max(),
            cost_bound,
            distance_bound,
        })
    }
}

/// Magnitude bounds of the scaled quantities of a solve.
pub(super) struct Intermediates {
    th: DVector<f64>,
    bv: DVector<f64>,
    by: DVector<f64>,
    bc: DVector<f64>,
    bw: DVector<f64>,
    /// The largest magnitude any intermediate reaches.
    pub(super) peak: f64,
}

/// `|fl(x) - x| <= u |x| + a`.
struct RoundModel {
    name: &'static str,
    u: f64,
    a: f64,
}

impl RoundModel {
    fn of<S: Scalar>() -> Self {
        // Fixed point maps infinity to its largest value; floats keep it.
        let fixed = S::from_f64(f64::INFINITY).is_finite();
        if fixed {
            RoundModel {
                name: "fixed",
                u: 0.0,
                a: 0.5 * S::RESOLUTION,
            }
        } else if S::RESOLUTION <= f64::EPSILON {
            RoundModel {
                name: "f64",
                u: 0.5 * S::RESOLUTION,
                a: 0.0,
            }
        } else {
            RoundModel {
                name: "f32",
                u: 0.5 * S::RESOLUTION,
                // Underflow: below the smallest normal f32 (ignored otherwise).
                a: 1e-37,
            }
        }
    }
    fn is_exact(&self) -> bool {
        self.name == "f64"
    }
    /// `gamma_k = k u / (1 - k u)` (float dot products); 0 for fixed point,
    /// whose dot products round once (covered by `a`).
    fn gamma(&self, k: usize) -> f64 {
        let ku = k as f64 * self.u;
        ku / (1.0 - ku)
    }
}
