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
//!
//! [`CertifySettings::merge`] trades exactness for reach: an upper bound
//! (`exact: false`) memoised per canonical solver state (after each full
//! dual step) and a few segments of history, for boxes whose exact
//! partition is too large (module `merge`, docs/qp-certify.md).
//! [`CertifySettings::union_merge`] stays exact and merges regions: those
//! reaching the same canonical state after the same count are merged
//! where their union is convex (module `union`; 3x fewer regions on the
//! larger problem's half box, the same worst-case iterations).

mod error;
mod estimate;
mod explore;
mod flops;
mod geometry;
mod merge;
mod model;
mod report;
mod settings;
mod step;
#[cfg(test)]
mod tests;
mod union;
mod warm;

pub use error::{CertifyError, Count};
pub use estimate::Estimate;
/// The solver settings a certificate mirrors ([`CertifySettings::qp`]).
pub use kestrel_qp::QpSettings;
pub use model::constraint_name;
pub use report::{Certificate, Certification, RegionReport};
pub use settings::{CertifySettings, Progress};
pub use step::{Change, Status};
pub use union::{UnionLevel, UnionStats};

use explore::{Ctx, Tally, run};
use geometry::{Geometry, Poly};
use kestrel_core::formats::MpqpProblem;
use kestrel_qp::parametric::ParametricQp;
use model::Model;
use std::time::Instant;
use step::Node;
use warm::{permutations, warm_region, warm_root};

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
    let mut cold_model =
        Model::new(&par, p, settings.qp).ok_or(CertifyError::NotPositiveDefinite)?;
    let mut geo = Geometry::new(settings.min_radius);
    let set = cold_model
        .parameter_set(&mut geo)
        .ok_or(CertifyError::EmptyParameterSet)?;
    check_bounds(&par, &cold_model, &mut geo, &set)?;
    if settings.merge.is_some() {
        return merge::certify_merged(&par, settings, progress);
    }
    let mut ctx = Ctx::new(settings, progress);
    let started = ctx.started;
    let n = par.n() as u64;
    let root = Node {
        poly: set,
        active: Vec::new(),
        mu: Vec::new(),
        dual: true,
        singular: false,
        fwd: 0,
        iterations: 0,
        flops: flops::preamble(n),
        path: Vec::new(),
        start: 0,
        mixed: false,
    };
    // The estimate walks the exact partition (no canonical stops); in
    // union-merge mode that partition bounds the merged one from above (the
    // merging keeps 1/3 to 1/2 of its regions on the measured problems), so
    // the same limits refuse a box before its frontier fills the memory.
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
    cold_model.canonical = settings.union_merge;
    let mut cold = Tally::default();
    let lps0 = geo.lps;
    let mut stats = UnionStats::default();
    let explore = |model: &Model,
                   geo: &mut Geometry,
                   root: Node,
                   ctx: &mut Ctx<'_>,
                   tally: &mut Tally,
                   finals: bool,
                   stats: &mut UnionStats| {
        if settings.union_merge {
            union::run_union(model, geo, root, ctx, tally, finals, stats)
        } else {
            run(model, geo, root, ctx, tally, finals)
        }
    };
    explore(
        &cold_model,
        &mut geo,
        root,
        &mut ctx,
        &mut cold,
        true,
        &mut stats,
    )?;
    let cold_time = started.elapsed();
    let mut cold_cert = report::certificate(
        &cold_model,
        &par,
        cold,
        (Vec::new(), Vec::new()),
        None,
        geo.lps - lps0,
        cold_time,
    );
    if settings.union_merge {
        cold_cert.union = Some(std::mem::take(&mut stats));
    }
    let warm = match settings.warm_step {
        None => None,
        Some(step) => {
            let finals = cold_cert.finals.clone();
            let t0 = Instant::now();
            let lps0 = geo.lps;
            let mut model =
                Model::new(&par, 2 * p, settings.qp).ok_or(CertifyError::NotPositiveDefinite)?;
            model.canonical = settings.union_merge;
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
                    explore(
                        &model, &mut geo, root, &mut ctx, &mut tally, false, &mut stats,
                    )?;
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
            if settings.union_merge {
                cert.union = Some(std::mem::take(&mut stats));
            }
            cert.start_sets = finals.len();
            Some(cert)
        }
    };
    Ok(Certification {
        cold: cold_cert,
        warm,
    })
}

/// Refuses a parameter set in which some constraint's bounds cross
/// (`l_j(theta) > u_j(theta)` on a piece with an interior, one LP per
/// constraint with both bounds): the solver refuses those parameters.
fn check_bounds(
    par: &ParametricQp,
    model: &Model,
    geo: &mut Geometry,
    set: &Poly,
) -> Result<(), CertifyError> {
    for j in 0..model.ncons {
        let (Some(lo), Some(hi)) = (&model.lo[j], &model.hi[j]) else {
            continue;
        };
        // u - l < 0.
        let f = geometry::minus(hi, lo);
        let h = geometry::half(&f, true, geometry::size(lo) + geometry::size(hi));
        if let Some(piece) = geo.restrict(set, &[h]) {
            let theta = model.theta(&piece.centre, 0);
            let at =
                |a: Option<&kestrel_qp::parametric::Affine>| a.map_or(f64::NAN, |a| a.eval(&theta));
            return Err(CertifyError::CrossedBounds {
                constraint: constraint_name(j, model.rows),
                lower: at(par.lower(j)),
                upper: at(par.upper(j)),
                theta,
            });
        }
    }
    Ok(())
}
