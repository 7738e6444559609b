//! Complexity certification of kestrel-qp's dual active-set solver:
//! the parameter set of a `kestrel.mpqp.v1` problem partitioned by the
//! sequence of active sets the solver visits, cold and warm started, with
//! the exact worst-case iteration count, a floating-point operation count
//! and the region where the worst case occurs.
//!
//! ```
//! use kestrel_empc::certify::{CertifySettings, certify};
//! let problem = kestrel_empc::testing::thesis_sized(1);
//! let settings = CertifySettings { warm_step: Some(0.01), ..CertifySettings::default() };
//! let c = certify(&problem, &settings, &mut |_| {})?;
//! assert!(c.cold.worst_iterations >= 1);
//! let warm = c.warm.as_ref().unwrap();
//! assert!(warm.worst_iterations <= c.cold.worst_iterations + 8);
//! # Ok::<(), kestrel_empc::certify::CertifyError>(())
//! ```
//!
//! The method (docs/qp-certify.md): regions carry the solver's state as
//! affine functions of the parameter (multipliers, primal point); each of
//! the solver's decisions splits a region by affine half-spaces (Arnström
//! and Axehill's framework, as ASCertain.jl does for DAQP), an LP (the
//! largest inscribed ball) keeps the pieces with an interior. A warm start
//! is certified in `(theta, theta_prev)`: `theta_prev` in the critical
//! region of an optimal active set (stored sorted by constraint index), `|
//! theta_k - theta_prev,k | <= step (ub_k - lb_k)`.

mod error;
mod estimate;
mod explore;
mod flops;
mod geometry;
mod model;
mod report;
mod settings;
mod step;
#[cfg(test)]
mod tests;

pub use error::CertifyError;
pub use estimate::Estimate;
/// The solver settings a certificate mirrors ([`CertifySettings::qp`]).
pub use kestrel_qp::QpSettings;
pub use model::constraint_name;
pub use report::{Certificate, Certification, RegionReport};
pub use settings::{CertifySettings, Progress};
pub use step::{Change, Status};

use explore::{Ctx, Tally, run};
use geometry::{Geometry, Half, Poly, half, minus, size};
use kestrel_core::formats::MpqpProblem;
use kestrel_qp::parametric::ParametricQp;
use model::{EQUALITY, Model, sign};
use std::time::Instant;
use step::Node;

/// Certifies kestrel-qp's solver on `problem` over its parameter box
/// (cold start, and warm start if `settings.warm_step` is set);
/// `progress` is called every few hundred regions.
pub fn certify(
    problem: &MpqpProblem,
    settings: &CertifySettings,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Certification, CertifyError> {
    settings.validate()?;
    let par = ParametricQp::from_mpqp(problem)?;
    let p = par.p();
    let cold_model = Model::new(&par, p, settings.qp).ok_or(CertifyError::NotPositiveDefinite)?;
    let started = Instant::now();
    let mut geo = Geometry::new(settings.min_radius);
    let mut ctx = Ctx {
        settings,
        started,
        progress,
        phase: "cold",
        sets_done: 0,
        sets_total: 0,
    };
    let n = par.n() as u64;
    let root = Node {
        poly: Poly::cube(p),
        active: Vec::new(),
        mu: Vec::new(),
        dual: true,
        singular: false,
        fwd: 0,
        iterations: 0,
        flops: flops::preamble(n),
        path: Vec::new(),
        start: 0,
    };
    if settings.estimate_probes > 0 {
        let e = estimate::estimate(&cold_model, &mut geo, &root, settings.estimate_probes)?;
        let report = Progress {
            estimate: Some(e),
            ..explore::progress(&ctx, &Tally::default(), &geo, 0)
        };
        (ctx.progress)(&report);
        let too_slow = settings
            .time_limit
            .is_some_and(|t| e.seconds > 4.0 * t.as_secs_f64());
        if e.regions > settings.max_regions as f64 || too_slow {
            return Err(CertifyError::TooLarge {
                regions: e.regions,
                seconds: e.seconds,
                max_regions: settings.max_regions,
                time_limit: settings.time_limit,
            });
        }
    }
    let mut cold = Tally::default();
    let lps0 = geo.lps;
    run(&cold_model, &mut geo, root, &mut ctx, &mut cold, true)?;
    let cold_time = started.elapsed();
    let cold_cert = report::certificate(
        &cold_model,
        &par,
        cold,
        (Vec::new(), Vec::new()),
        None,
        geo.lps - lps0,
        cold_time,
    );
    let warm = match settings.warm_step {
        None => None,
        Some(step) => {
            let finals = cold_cert.finals.clone();
            let t0 = Instant::now();
            let lps0 = geo.lps;
            let model =
                Model::new(&par, 2 * p, settings.qp).ok_or(CertifyError::NotPositiveDefinite)?;
            ctx.phase = "warm";
            ctx.sets_total = finals.len();
            let mut tally = Tally::default();
            // One root per start order: its stored order and start region.
            let (mut orders, mut regions) = (Vec::new(), Vec::new());
            for (id, set) in finals.iter().enumerate() {
                ctx.sets_done = id;
                let Some(poly) = warm_region(&cold_model, &mut geo, set, step) else {
                    continue;
                };
                let perms = if settings.warm_any_order {
                    permutations(set)?
                } else {
                    vec![set.clone()]
                };
                for order in perms {
                    let root = warm_root(&model, &order, poly.clone(), orders.len(), n);
                    orders.push(order);
                    regions.push((poly.a.clone(), poly.b.clone()));
                    run(&model, &mut geo, root, &mut ctx, &mut tally, false)?;
                }
            }
            let mut cert = report::certificate(
                &model,
                &par,
                tally,
                (orders, regions),
                Some(step),
                geo.lps - lps0,
                t0.elapsed(),
            );
            cert.any_order = settings.warm_any_order;
            cert.start_sets = finals.len();
            Some(cert)
        }
    };
    Ok(Certification {
        cold: cold_cert,
        warm,
    })
}

/// Every order of `set` (at most 8! = 40,320).
fn permutations(set: &[(usize, u8)]) -> Result<Vec<Vec<(usize, u8)>>, CertifyError> {
    if set.len() > 8 {
        return Err(CertifyError::InvalidSettings(format!(
            "warm_any_order: a start set has {} constraints, more than 8! orders",
            set.len()
        )));
    }
    let mut out = vec![Vec::new()];
    for &c in set {
        out = out
            .into_iter()
            .flat_map(|o: Vec<(usize, u8)>| {
                (0..=o.len()).map(move |i| {
                    let mut v = o.clone();
                    v.insert(i, c);
                    v
                })
            })
            .collect();
    }
    Ok(out)
}

/// The start region of a warm start from `set`: `theta_prev` (columns
/// `p..2p`) in the critical region of `set`, `theta` in the box and
/// within the step.
fn warm_region(cold: &Model, geo: &mut Geometry, set: &[(usize, u8)], step: f64) -> Option<Poly> {
    let p = cold.p;
    let d = 2 * p;
    let lift = |f: &[f64]| {
        let mut g = vec![0.0; d + 1];
        g[p..d].copy_from_slice(&f[..p]);
        g[d] = f[p];
        g
    };
    let mut hs: Vec<Half> = Vec::new();
    // |s_k - sp_k| <= 2 step (the box is [-1, 1]).
    for k in 0..p {
        for sgn in [1.0, -1.0] {
            let mut row = vec![0.0; d];
            row[k] = sgn / 2f64.sqrt();
            row[p + k] = -sgn / 2f64.sqrt();
            hs.push(Half::Row(row, 2.0 * step / 2f64.sqrt()));
        }
    }
    let mustar = cold.mustar(set)?;
    for (&(_, code), m) in set.iter().zip(&mustar) {
        if code & EQUALITY == 0 {
            let f: Vec<f64> = m.iter().map(|v| -sign(code) * v).collect();
            hs.push(half(&lift(&f), false, size(m)));
        }
    }
    let mut active = vec![false; cold.ncons];
    for &(j, _) in set {
        active[j] = true;
    }
    for j in (0..cold.ncons).filter(|&j| !active[j]) {
        let v = cold.value(j, set, &mustar);
        if let Some(hi) = &cold.hi[j] {
            let f = minus(&v, hi);
            hs.push(half(&lift(&f), false, size(&v) + size(hi)));
        }
        if let Some(lo) = &cold.lo[j] {
            let f = minus(lo, &v);
            hs.push(half(&lift(&f), false, size(&v) + size(lo)));
        }
    }
    geo.restrict(&Poly::cube(d), &hs)
}

/// The solver's state after re-adding `set` (sorted) from `mu = 0`:
/// dependent constraints and infinite bounds dropped.
fn warm_root(model: &Model, set: &[(usize, u8)], poly: Poly, id: usize, n: u64) -> Node {
    let mut active: Vec<(usize, u8)> = Vec::new();
    let mut flops = flops::preamble(n);
    for &(j, code) in set {
        if model.bound(j, code).is_none() || active.len() > model.n {
            continue;
        }
        let rows = active.iter().filter(|a| a.0 < model.rows).count() as u64;
        flops += flops::add(n, active.len() as u64, j < model.rows, rows);
        if !model.dependent(&active, j) {
            active.push((j, code));
        }
    }
    let k = active.len();
    Node {
        poly,
        active,
        mu: vec![vec![0.0; model.d + 1]; k],
        dual: false,
        singular: false,
        fwd: 0,
        iterations: 0,
        flops,
        path: Vec::new(),
        start: id,
    }
}
