//! The complexity certificate of kestrel-qp's solver against the solver
//! itself: at sampled parameters (cold, and warm from the previous
//! parameter's optimal active set within the step) no solve takes more
//! iterations than certified, each takes exactly its region's count, and
//! the worst region's interior point takes exactly the worst case.
//!
//! `KESTREL_CERTIFY_SAMPLES=N` sets the samples per problem and start
//! (default 1,000; the issue's 10^4: `KESTREL_CERTIFY_SAMPLES=10000 cargo
//! test -p kestrel-empc --test certify --release`).

use kestrel_core::formats::MpqpProblem;
use kestrel_empc::certify::{Certificate, CertifyError, CertifySettings, certify};
use kestrel_qp::parametric::ParametricQp;
use kestrel_qp::{ActiveConstraint, QpSettings, QpSolver, Start};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

fn samples() -> usize {
    std::env::var("KESTREL_CERTIFY_SAMPLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000)
}

/// Solves at `theta` from `start` (warm: from `set`): iterations and the
/// final active set sorted by index (in the solver's order with
/// `SORTED = false`).
fn solve_in<const SORTED: bool>(
    qp: &mut QpSolver<'_, f64>,
    par: &ParametricQp,
    theta: &[f64],
    set: Option<&[ActiveConstraint]>,
) -> (usize, Vec<ActiveConstraint>) {
    let mut buf = par.buffers::<f64>();
    par.fill(theta, &mut buf).unwrap();
    let start = match set {
        Some(s) => {
            qp.set_active_set(s).unwrap();
            Start::Warm
        }
        None => Start::Cold,
    };
    let info = qp.solve(&buf.data(), start).unwrap();
    let mut fin: Vec<ActiveConstraint> = qp.active_set().collect();
    if SORTED {
        fin.sort_by_key(|a| a.index);
    }
    (info.iterations, fin)
}

fn solve(
    qp: &mut QpSolver<'_, f64>,
    par: &ParametricQp,
    theta: &[f64],
    set: Option<&[ActiveConstraint]>,
) -> (usize, Vec<ActiveConstraint>) {
    solve_in::<true>(qp, par, theta, set)
}

/// Checks one certificate; returns (samples located in a region, samples).
fn check_start(
    name: &str,
    p: &MpqpProblem,
    cert: &Certificate,
    warm: Option<f64>,
    count: usize,
) -> (usize, usize) {
    let par = ParametricQp::from_mpqp(p).unwrap();
    let (ns, ni) = par.workspace_len();
    let (mut s, mut ix) = (vec![0.0; ns], vec![0; ni]);
    let mut qp = par.solver(QpSettings::default(), &mut s, &mut ix).unwrap();
    let mut rng = SplitMix64::seed_from_u64(2024);
    let (lb, ub) = (par.theta_lb().to_vec(), par.theta_ub().to_vec());
    let mut located = 0;
    let mut most = 0;
    let mut done = 0;
    while done < count {
        // Uniform in the parameter set (the box, cut by theta_poly if any).
        let prev: Vec<f64> = (0..par.p())
            .map(|k| lb[k] + (ub[k] - lb[k]) * rng.random::<f64>())
            .collect();
        if !par.contains(&prev, 0.0) {
            continue;
        }
        let (theta, it, at) = match warm {
            None => {
                let (it, _) = solve(&mut qp, &par, &prev, None);
                (prev.clone(), it, cert.iterations_at(&prev, None))
            }
            Some(step) => {
                let theta: Vec<f64> = (0..par.p())
                    .map(|k| {
                        let d = step * (ub[k] - lb[k]) * (2.0 * rng.random::<f64>() - 1.0);
                        (prev[k] + d).clamp(lb[k], ub[k])
                    })
                    .collect();
                if !par.contains(&theta, 0.0) {
                    continue;
                }
                let (_, set) = solve(&mut qp, &par, &prev, None);
                let (it, _) = solve(&mut qp, &par, &theta, Some(&set));
                let at = cert.iterations_at(&theta, Some(&prev));
                (theta, it, at)
            }
        };
        done += 1;
        most = most.max(it);
        assert!(
            it <= cert.worst_iterations,
            "{name}: {it} iterations at {theta:?} (previous {prev:?}), certified {}",
            cert.worst_iterations
        );
        if let Some((ci, _)) = at {
            located += 1;
            assert_eq!(
                it, ci,
                "{name}: {it} iterations at {theta:?} (previous {prev:?}), its region says {ci}"
            );
        }
    }
    // The worst region's interior point takes exactly the worst case.
    let w = cert.worst.as_ref().unwrap();
    let it = match &w.theta_prev {
        None => solve(&mut qp, &par, &w.theta, None).0,
        Some(prev) => {
            let (_, set) = solve(&mut qp, &par, prev, None);
            assert_eq!(set, w.start_set, "{name}: start set of the worst region");
            solve(&mut qp, &par, &w.theta, Some(&set)).0
        }
    };
    assert_eq!(
        it, cert.worst_iterations,
        "{name}: the worst region's point {:?} takes {it}",
        w.theta
    );
    eprintln!(
        "{name}: certified {} iterations, {} flops, {} regions ({:.2} s); {count} samples, {located} located, most {most}",
        cert.worst_iterations,
        cert.worst_flops,
        cert.regions,
        cert.elapsed.as_secs_f64()
    );
    (located, count)
}

fn check(name: &str, p: &MpqpProblem, step: f64) {
    let settings = CertifySettings {
        warm_step: Some(step),
        ..CertifySettings::default()
    };
    let mut estimate = None;
    let c = certify(p, &settings, &mut |pr| estimate = estimate.or(pr.estimate)).unwrap();
    // The up-front estimate of the cold partition is within a factor 2.
    let e = estimate.unwrap().regions;
    let r = c.cold.regions as f64;
    assert!(
        e >= 0.5 * r && e <= 2.0 * r,
        "{name}: estimated {e}, found {r}"
    );
    let n = samples();
    let (lc, nc) = check_start(&format!("{name} cold"), p, &c.cold, None, n);
    let warm = c.warm.as_ref().unwrap();
    let (lw, nw) = check_start(&format!("{name} warm {step}"), p, warm, Some(step), n);
    // Samples on no region lie on dropped slivers: almost never.
    assert!(
        lc * 100 >= nc * 99 && lw * 100 >= nw * 99,
        "{name}: {lc}/{nc}, {lw}/{nw} located"
    );
    assert!(c.cold.exact && warm.exact);
}

#[test]
fn random_thesis_sized_problems() {
    for seed in [1, 2, 3] {
        let p = kestrel_empc::testing::thesis_sized(seed);
        check(&format!("thesis_sized({seed})"), &p, 0.05);
    }
}

/// A parameter set cut by `theta_poly`: the certificate covers the set,
/// not the box. Sampled in the set (cold and warm), every solve takes its
/// region's count and never more than certified, the worst region's point
/// lies in the set, and the worst case is at most the whole box's.
#[test]
fn parameter_polytope_is_certified_not_the_box() {
    let mut p = kestrel_empc::testing::thesis_sized(1);
    let box_cert = certify(&p, &CertifySettings::default(), &mut |_| {}).unwrap();
    // Cut off the box's corner where the first three parameters are all
    // large: s_0 + s_1 + s_2 <= 0.5 in the normalised box.
    let (lb, ub) = (p.theta_lb.clone(), p.theta_ub.clone());
    let half = |k: usize| 0.5 * (ub[k] - lb[k]);
    let mid = |k: usize| 0.5 * (ub[k] + lb[k]);
    let a = nalgebra::DMatrix::from_fn(1, p.p(), |_, k| if k < 3 { 1.0 / half(k) } else { 0.0 });
    let b = nalgebra::DVector::from_element(1, 0.5 + (0..3).map(|k| mid(k) / half(k)).sum::<f64>());
    p.theta_poly = Some((a, b));
    let par = ParametricQp::from_mpqp(&p).unwrap();
    check("thesis_sized(1) cut", &p, 0.05);
    let c = certify(&p, &CertifySettings::default(), &mut |_| {}).unwrap();
    let w = c.cold.worst.as_ref().unwrap();
    assert!(par.contains(&w.theta, 1e-9), "{:?}", w.theta);
    assert!(c.cold.worst_iterations <= box_cert.cold.worst_iterations);
    assert!(
        c.cold.regions < box_cert.cold.regions,
        "{} regions in the cut set, {} in the box",
        c.cold.regions,
        box_cert.cold.regions
    );
    // The merged (upper-bound) mode covers the same set.
    let merged = CertifySettings {
        merge: Some(2),
        ..CertifySettings::default()
    };
    let m = certify(&p, &merged, &mut |_| {}).unwrap();
    assert!(m.cold.worst_iterations >= c.cold.worst_iterations && !m.cold.exact);
    // A polytope that leaves nothing of the box is refused.
    let far =
        nalgebra::DVector::from_element(1, -10.0 + (0..3).map(|k| mid(k) / half(k)).sum::<f64>());
    p.theta_poly = Some((p.theta_poly.unwrap().0, far));
    let err = certify(&p, &CertifySettings::default(), &mut |_| {}).unwrap_err();
    assert!(matches!(err, CertifyError::EmptyParameterSet), "{err}");
}

/// Bounds that cross on part of the parameter set (`0 <= z <= theta`
/// with `theta` in `[-1, 1]`): the solver refuses those parameters, so
/// the certification refuses the set and names the constraint and a
/// parameter where they cross; cut to `theta >= 0.1` it certifies.
#[test]
fn crossed_bounds_are_refused() {
    let text = r#"{"format": "kestrel.mpqp.v1", "H": [[2]], "F": [[1]],
        "G": [[1], [-1]], "W": [0, 0], "E": [[1], [0]],
        "theta_lb": [-1], "theta_ub": [1]}"#;
    let mut p = MpqpProblem::from_json_str(text).unwrap();
    let err = certify(&p, &CertifySettings::default(), &mut |_| {}).unwrap_err();
    match &err {
        CertifyError::CrossedBounds {
            constraint,
            theta,
            lower,
            upper,
        } => {
            assert_eq!(constraint, "b0");
            assert!(theta[0] < 0.0, "{theta:?}");
            assert!((lower - 0.0).abs() < 1e-12 && (upper - theta[0]).abs() < 1e-12);
            assert!(lower > upper);
        }
        e => panic!("{e}"),
    }
    assert!(err.to_string().contains("constraint b0"), "{err}");
    // The solver itself refuses such a parameter.
    let par = ParametricQp::from_mpqp(&p).unwrap();
    let (ns, ni) = par.workspace_len();
    let (mut s, mut ix) = (vec![0.0; ns], vec![0; ni]);
    let mut qp = par.solver(QpSettings::default(), &mut s, &mut ix).unwrap();
    let mut buf = par.buffers::<f64>();
    par.fill(&[-0.5], &mut buf).unwrap();
    assert_eq!(
        qp.solve(&buf.data(), Start::Cold),
        Err(kestrel_qp::QpError::InvalidBounds)
    );
    // theta >= 0.1: -theta <= -0.1.
    p.theta_poly = Some((nalgebra::dmatrix![-1.0], nalgebra::dvector![-0.1]));
    check("0 <= z <= theta, theta >= 0.1", &p, 0.05);
}

/// Warm start in any stored order: the solver's own order (the order it
/// added the constraints in) never takes more than the certificate's
/// count at the point, the most over all orders.
#[test]
fn warm_start_in_any_order() {
    let p = kestrel_empc::testing::thesis_sized(2);
    let step = 0.05;
    let settings = CertifySettings {
        warm_step: Some(step),
        warm_any_order: true,
        ..CertifySettings::default()
    };
    let c = certify(&p, &settings, &mut |_| {}).unwrap();
    let warm = c.warm.as_ref().unwrap();
    assert!(warm.any_order);
    let par = ParametricQp::from_mpqp(&p).unwrap();
    let (ns, ni) = par.workspace_len();
    let (mut s, mut ix) = (vec![0.0; ns], vec![0; ni]);
    let mut qp = par.solver(QpSettings::default(), &mut s, &mut ix).unwrap();
    let mut rng = SplitMix64::seed_from_u64(99);
    let (lb, ub) = (par.theta_lb().to_vec(), par.theta_ub().to_vec());
    for _ in 0..samples() {
        let prev: Vec<f64> = (0..par.p())
            .map(|k| lb[k] + (ub[k] - lb[k]) * rng.random::<f64>())
            .collect();
        let (_, set) = solve_in::<false>(&mut qp, &par, &prev, None);
        let theta: Vec<f64> = (0..par.p())
            .map(|k| {
                let d = step * (ub[k] - lb[k]) * (2.0 * rng.random::<f64>() - 1.0);
                (prev[k] + d).clamp(lb[k], ub[k])
            })
            .collect();
        let (it, _) = solve_in::<false>(&mut qp, &par, &theta, Some(&set));
        assert!(it <= warm.worst_iterations);
        if let Some((ci, _)) = warm.iterations_at(&theta, Some(&prev)) {
            assert!(
                it <= ci,
                "{it} iterations at {theta:?} from {prev:?}, certified {ci}"
            );
        }
    }
    eprintln!(
        "thesis_sized(2) warm {step} any order: certified {} iterations, {} regions, {} start sets",
        warm.worst_iterations, warm.regions, warm.start_sets
    );
}

mod counted {
    //! An `f64` that counts its arithmetic operators (`+ - * /`; a
    //! multiply-add two; negation free), to measure the flop model.
    use kestrel_core::Scalar;
    use std::cell::Cell;
    use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

    thread_local!(static OPS: Cell<u64> = const { Cell::new(0) });

    /// Operators counted since the last call.
    pub fn take() -> u64 {
        OPS.with(|c| c.replace(0))
    }

    fn tick() {
        OPS.with(|c| c.set(c.get() + 1));
    }

    #[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
    pub struct C(pub f64);

    macro_rules! op {
        ($tr:ident, $f:ident, $o:tt, $tra:ident, $fa:ident) => {
            impl $tr for C {
                type Output = C;
                fn $f(self, r: C) -> C {
                    tick();
                    C(self.0 $o r.0)
                }
            }
            impl $tra for C {
                fn $fa(&mut self, r: C) {
                    tick();
                    self.0 = self.0 $o r.0;
                }
            }
        };
    }
    op!(Add, add, +, AddAssign, add_assign);
    op!(Sub, sub, -, SubAssign, sub_assign);
    op!(Mul, mul, *, MulAssign, mul_assign);
    impl Div for C {
        type Output = C;
        fn div(self, r: C) -> C {
            tick();
            C(self.0 / r.0)
        }
    }
    impl Neg for C {
        type Output = C;
        fn neg(self) -> C {
            C(-self.0)
        }
    }
    impl Scalar for C {
        const ZERO: C = C(0.0);
        const ONE: C = C(1.0);
        const MAX: C = C(f64::MAX);
        const MIN: C = C(f64::MIN);
        const RESOLUTION: f64 = f64::EPSILON;
        fn from_f64(v: f64) -> C {
            C(v)
        }
        fn to_f64(self) -> f64 {
            self.0
        }
        fn is_finite(self) -> bool {
            self.0.is_finite()
        }
    }
}

/// The flop model against the solver's operators counted by a counting
/// scalar: at sampled theta (cold, and warm within the step) the counted
/// operators of a solve never exceed its region's certified flops, and
/// cold solves of regions without a multi-candidate dual step match.
#[test]
fn flop_model_bounds_the_counted_operators() {
    use counted::C;
    // Cold and warm on seed 2 (a small warm partition), cold on seed 1.
    for (seed, with_warm) in [(2, true), (1, false)] {
        let p = kestrel_empc::testing::thesis_sized(seed);
        let step = 0.05;
        let settings = CertifySettings {
            warm_step: with_warm.then_some(step),
            ..CertifySettings::default()
        };
        let c = certify(&p, &settings, &mut |_| {}).unwrap();
        let par = ParametricQp::from_mpqp(&p).unwrap();
        let (ns, ni) = par.workspace_len();
        let (mut s, mut ix) = (vec![C(0.0); ns], vec![0; ni]);
        let mut qp = par
            .solver::<C>(QpSettings::default(), &mut s, &mut ix)
            .unwrap();
        let mut buf = par.buffers::<C>();
        let mut rng = SplitMix64::seed_from_u64(5);
        let (lb, ub) = (par.theta_lb().to_vec(), par.theta_ub().to_vec());
        let (mut exact, mut worst_gap, mut count) = (0, 0u64, 0);
        for _ in 0..samples() / 4 {
            let prev: Vec<f64> = (0..par.p())
                .map(|k| lb[k] + (ub[k] - lb[k]) * rng.random::<f64>())
                .collect();
            par.fill(&prev, &mut buf).unwrap();
            counted::take();
            qp.solve(&buf.data(), Start::Cold).unwrap();
            let ops = counted::take();
            let mut set: Vec<ActiveConstraint> = qp.active_set().collect();
            set.sort_by_key(|a| a.index);
            if let Some((_, f)) = c.cold.iterations_at(&prev, None) {
                assert!(ops <= f, "cold at {prev:?}: {ops} counted, {f} certified");
                exact += usize::from(ops == f);
                worst_gap = worst_gap.max(f - ops);
                count += 1;
            }
            let theta: Vec<f64> = (0..par.p())
                .map(|k| {
                    let d = step * (ub[k] - lb[k]) * (2.0 * rng.random::<f64>() - 1.0);
                    (prev[k] + d).clamp(lb[k], ub[k])
                })
                .collect();
            par.fill(&theta, &mut buf).unwrap();
            qp.set_active_set(&set).unwrap();
            counted::take();
            qp.solve(&buf.data(), Start::Warm).unwrap();
            let ops = counted::take();
            let Some(warm) = c.warm.as_ref() else {
                continue;
            };
            if let Some((_, f)) = warm.iterations_at(&theta, Some(&prev)) {
                assert!(ops <= f, "warm at {theta:?}: {ops} counted, {f} certified");
                exact += usize::from(ops == f);
                worst_gap = worst_gap.max(f - ops);
                count += 1;
            }
        }
        assert!(
            exact * 2 >= count,
            "thesis_sized({seed}): only {exact} of {count} exact"
        );
        eprintln!(
            "thesis_sized({seed}): flops counted = certified on {exact} of {count} solves, largest over-count {worst_gap}"
        );
    }
}

/// The larger tricopter problem (`N = 10`, blocks `[1, 1, 2, 6]`), as
/// `kestrel codegen` writes it for kestrel-avr-rt's tests.
fn larger() -> MpqpProblem {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../avr-rt/tests/data/qp16-larger.mpqp.json"
    );
    MpqpProblem::read(std::path::Path::new(path)).unwrap()
}

/// Iterations of kestrel-qp at `count` sampled parameters (cold, or warm
/// from the previous sample's optimal active set sorted within `warm`):
/// the most.
fn most_sampled(p: &MpqpProblem, warm: Option<f64>, count: usize, seed: u64) -> usize {
    let par = ParametricQp::from_mpqp(p).unwrap();
    let (ns, ni) = par.workspace_len();
    let (mut s, mut ix) = (vec![0.0; ns], vec![0; ni]);
    let mut qp = par.solver(QpSettings::default(), &mut s, &mut ix).unwrap();
    let mut rng = SplitMix64::seed_from_u64(seed);
    let (lb, ub) = (par.theta_lb().to_vec(), par.theta_ub().to_vec());
    let mut most = 0;
    for _ in 0..count {
        let prev: Vec<f64> = (0..par.p())
            .map(|k| lb[k] + (ub[k] - lb[k]) * rng.random::<f64>())
            .collect();
        let (it, set) = solve(&mut qp, &par, &prev, None);
        let it = match warm {
            None => it,
            Some(step) => {
                let theta: Vec<f64> = (0..par.p())
                    .map(|k| {
                        let d = step * (ub[k] - lb[k]) * (2.0 * rng.random::<f64>() - 1.0);
                        (prev[k] + d).clamp(lb[k], ub[k])
                    })
                    .collect();
                solve(&mut qp, &par, &theta, Some(&set)).0
            }
        };
        most = most.max(it);
    }
    most
}

/// The merged (over-approximating) certificate against the exact one and
/// the solver: never below the exact worst case (iterations and flops),
/// never below a sampled solve, marked not exact.
#[test]
fn merged_certificate_bounds_the_exact_one() {
    let mut larger1 = larger();
    larger1.scale_parameter_box(0.1);
    let mut larger2 = larger();
    larger2.scale_parameter_box(0.2);
    let cases: Vec<(String, MpqpProblem, Option<f64>)> = vec![
        (
            "thesis_sized(1)".into(),
            kestrel_empc::testing::thesis_sized(1),
            None,
        ),
        (
            "thesis_sized(2)".into(),
            kestrel_empc::testing::thesis_sized(2),
            Some(0.05),
        ),
        (
            "thesis_sized(3)".into(),
            kestrel_empc::testing::thesis_sized(3),
            None,
        ),
        ("larger x 0.1".into(), larger1, Some(0.05)),
        ("larger x 0.2".into(), larger2, None),
    ];
    let n = samples();
    for (name, p, warm_step) in cases {
        let exact = certify(
            &p,
            &CertifySettings {
                warm_step,
                estimate_probes: 0,
                keep_regions: false,
                ..CertifySettings::default()
            },
            &mut |_| {},
        )
        .unwrap();
        let merged = certify(
            &p,
            &CertifySettings {
                warm_step,
                merge: Some(2),
                ..CertifySettings::default()
            },
            &mut |_| {},
        )
        .unwrap();
        let mut pairs = vec![("cold", &exact.cold, &merged.cold, None)];
        if let (Some(e), Some(m)) = (&exact.warm, &merged.warm) {
            pairs.push(("warm", e, m, warm_step));
        }
        for (start, e, m, step) in pairs {
            assert!(e.exact && !m.exact);
            assert!(
                m.worst_iterations >= e.worst_iterations && m.worst_flops >= e.worst_flops,
                "{name} {start}: merged {} it / {} flops below exact {} / {}",
                m.worst_iterations,
                m.worst_flops,
                e.worst_iterations,
                e.worst_flops
            );
            let most = most_sampled(&p, step, n, 7);
            assert!(most <= m.worst_iterations, "{name} {start}: sampled {most}");
            // The worst chain is a path of the bound's length.
            let w = m.worst.as_ref().unwrap();
            assert!(w.path.len() <= m.worst_iterations, "{name} {start}");
            eprintln!(
                "{name} {start}: merged {} it / {} flops ({} bounds, {:.2} s), exact {} / {} ({} regions, {:.2} s), sampled {most}",
                m.worst_iterations,
                m.worst_flops,
                m.regions,
                m.elapsed.as_secs_f64(),
                e.worst_iterations,
                e.worst_flops,
                e.regions,
                e.elapsed.as_secs_f64()
            );
        }
    }
}

#[test]
#[ignore]
fn merged_experiment() {
    let scale: f64 = std::env::var("KESTREL_MERGE_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.1);
    let exact = std::env::var("KESTREL_MERGE_EXACT").is_ok();
    let mut p = larger();
    p.scale_parameter_box(scale);
    let mut probs = vec![(format!("larger x {scale}"), p)];
    for seed in [1, 2, 3] {
        probs.push((
            format!("thesis_sized({seed})"),
            kestrel_empc::testing::thesis_sized(seed),
        ));
    }
    for (name, p) in probs {
        let depth: usize = std::env::var("KESTREL_MERGE_DEPTH")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(1);
        let settings = CertifySettings {
            merge: Some(depth),
            time_limit: None,
            ..CertifySettings::default()
        };
        let mut last = 0.0;
        let c = certify(&p, &settings, &mut |pr| {
            let t = pr.elapsed.as_secs_f64();
            if t > last + 30.0 {
                last = t;
                eprintln!(
                    "{name}: {t:.0} s, {} bounds, {} nodes, {} LPs, {} open, worst so far {}",
                    pr.states, pr.nodes, pr.lps, pr.open, pr.worst_iterations
                );
            }
        })
        .unwrap();
        eprintln!("{name} merged: {}", c.cold);
        if std::env::var("KESTREL_MERGE_ONLY_LARGER").is_ok() {
            return;
        }
        if exact {
            let e = certify(&p, &CertifySettings::default(), &mut |_| {}).unwrap();
            eprintln!(
                "{name} exact: {} it {} flops",
                e.cold.worst_iterations, e.cold.worst_flops
            );
        }
    }
}

/// The union-merge certificate (regions at the same canonical state and
/// count merged where their union is convex) against the exact
/// enumeration: the same worst-case iterations, flops never below, fewer
/// regions, and the same sampled validation as the exact certificates
/// (no sample above the certificate, each sample takes its region's count,
/// the worst region's point takes the worst case). The larger problem's
/// 0.3 box is compared with the exact enumeration's 12 iterations
/// (docs/qp-certify.md; that enumeration takes about a minute).
#[test]
fn union_merge_equals_the_exact_certificate() {
    let scaled = |f: f64| {
        let mut p = larger();
        p.scale_parameter_box(f);
        p
    };
    let cases: Vec<(String, MpqpProblem, Option<f64>, Option<usize>)> = vec![
        (
            "thesis_sized(1)".into(),
            kestrel_empc::testing::thesis_sized(1),
            None,
            None,
        ),
        (
            "thesis_sized(2)".into(),
            kestrel_empc::testing::thesis_sized(2),
            Some(0.05),
            None,
        ),
        (
            "thesis_sized(3)".into(),
            kestrel_empc::testing::thesis_sized(3),
            None,
            None,
        ),
        ("larger x 0.1".into(), scaled(0.1), Some(0.05), None),
        ("larger x 0.2".into(), scaled(0.2), None, None),
        ("larger x 0.3".into(), scaled(0.3), None, Some(12)),
    ];
    let n = samples();
    for (name, p, warm_step, known) in cases {
        let union = certify(
            &p,
            &CertifySettings {
                warm_step,
                union_merge: true,
                ..CertifySettings::default()
            },
            &mut |_| {},
        )
        .unwrap();
        let exact = match known {
            Some(_) => None,
            None => Some(
                certify(
                    &p,
                    &CertifySettings {
                        warm_step,
                        estimate_probes: 0,
                        keep_regions: false,
                        ..CertifySettings::default()
                    },
                    &mut |_| {},
                )
                .unwrap(),
            ),
        };
        let mut starts = vec![("cold", &union.cold, exact.as_ref().map(|e| &e.cold), None)];
        if let Some(w) = &union.warm {
            let e = exact.as_ref().and_then(|e| e.warm.as_ref());
            starts.push(("warm", w, e, warm_step));
        }
        for (start, u, e, step) in starts {
            let label = format!("{name} {start} (union merge)");
            assert!(u.exact && u.union.is_some(), "{label}");
            match e {
                Some(e) => {
                    assert_eq!(u.worst_iterations, e.worst_iterations, "{label}");
                    assert!(u.worst_flops >= e.worst_flops, "{label}");
                    assert!(u.regions <= e.regions, "{label}");
                    if u.union.as_ref().unwrap().flops_exact() {
                        assert_eq!(u.worst_flops, e.worst_flops, "{label}");
                    }
                }
                None => assert_eq!(Some(u.worst_iterations), known, "{label}"),
            }
            let (located, count) = check_start(&label, &p, u, step, n);
            assert!(
                located * 100 >= count * 99,
                "{label}: {located}/{count} located"
            );
        }
    }
}

/// The union-merge certificate of the larger problem on a scaled box
/// (`KESTREL_UNION_SCALE`, default 0.2;
/// `KESTREL_UNION_WARM=0.05` also warm; `KESTREL_UNION_COMPARE=1` also
/// the exact enumeration; `KESTREL_UNION_TIME` seconds, default none;
/// `KESTREL_UNION_MAX_REGIONS`, default 2,000,000): regions and merges per
/// iteration count.
#[test]
#[ignore]
fn union_experiment() {
    let env = |k: &str| std::env::var(k).ok();
    let scale: f64 = env("KESTREL_UNION_SCALE")
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.2);
    let mut p = larger();
    p.scale_parameter_box(scale);
    let settings = CertifySettings {
        union_merge: true,
        warm_step: env("KESTREL_UNION_WARM").and_then(|s| s.parse().ok()),
        keep_regions: false,
        time_limit: env("KESTREL_UNION_TIME")
            .and_then(|s| s.parse().ok())
            .map(std::time::Duration::from_secs),
        max_regions: env("KESTREL_UNION_MAX_REGIONS")
            .and_then(|s| s.parse().ok())
            .unwrap_or(2_000_000),
        ..CertifySettings::default()
    };
    let mut last = 0.0;
    let c = certify(&p, &settings, &mut |pr| {
        let t = pr.elapsed.as_secs_f64();
        if t > last + 30.0 {
            last = t;
            eprintln!(
                "{:.0} s {}: {} regions, {} nodes, {} open, {} LPs, worst so far {}",
                t, pr.phase, pr.regions, pr.nodes, pr.open, pr.lps, pr.worst_iterations
            );
        }
    })
    .unwrap();
    for cert in std::iter::once(&c.cold).chain(c.warm.as_ref()) {
        eprintln!("{cert}");
        let u = cert.union.as_ref().unwrap();
        for l in &u.levels {
            eprintln!(
                "  it {:2}: canonical {:8} groups {:7} merged {:7}",
                l.iterations, l.canonical, l.groups, l.merged
            );
        }
        eprintln!(
            "  pairs tested {}, merges {}, flops differed {}, orders differed {}",
            u.pairs_tested, u.merges, u.flops_differed, u.orders_differed
        );
    }
    if env("KESTREL_UNION_COMPARE").is_some() {
        let e = certify(
            &p,
            &CertifySettings {
                estimate_probes: 0,
                keep_regions: false,
                time_limit: None,
                union_merge: false,
                ..settings.clone()
            },
            &mut |_| {},
        );
        let _ = e.map(|e| eprintln!("exact: {}", e.cold));
    }
}
