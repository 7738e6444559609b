//! kestrel-qp's dual active-set solver on MPC problems, against
//! kestrel-mpc's clarabel ReferenceSolver (polished: the exact KKT solution
//! of its active set) and, where it exists, kestrel-empc's explicit law
//! (the region containing theta, its affine law).
//!
//! Problems: the tricopter thesis-sized problem (identified 5-state
//! black-box model `models/tricopter-blackbox-5.json`, `N = 2`, `N_s = 1`,
//! pulses in us: badly scaled), kestrel-empc's random thesis-sized problems
//! (`testing::thesis_sized`), and the larger tricopter problem (`N = 10`,
//! blocks `[1, 1, 2, 6]`: no explicit law, clarabel only). Rows of `G`
//! that bound a single variable become the solver's simple bounds (no
//! row), the rest are one-sided rows `G z <= W + E theta`.
//!
//! The sample count is 10^4 theta per problem (`KESTREL_QP_SAMPLES=N`
//! overrides it); the whole file runs in about 5 s in the dev profile.

use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_empc::{Settings, solve as solve_mpqp};
use kestrel_mpc::{QpSettings as RefSettings, ReferenceSolver};
use kestrel_qp::{QpData, QpSettings, QpSolver, Start, index_len, scalar_len};
use kestrel_tricopter::{ProblemSize, default_weights, tricopter_problem};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

fn samples(default: usize) -> usize {
    std::env::var("KESTREL_QP_SAMPLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn tricopter(size: ProblemSize) -> MpqpProblem {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../models/tricopter-blackbox-5.json"
    );
    let model = SsModel::read(std::path::Path::new(path)).unwrap();
    let (q1, q2) = default_weights();
    tricopter_problem(&model, size, q1, q2).unwrap().to_mpqp()
}

/// The problem split into double-sided general rows and simple bounds.
struct Split {
    n: usize,
    h: Vec<f64>,
    g: Vec<f64>,
    /// The mpQP rows of each general row's upper and lower bound (`-g'z <=
    /// r` is the lower bound `g'z >= -r` of the row `g`).
    rows: Vec<(Option<usize>, Option<usize>)>,
    /// `(row, variable, coefficient)` of each single-variable row.
    bounds: Vec<(usize, usize, f64)>,
}

impl Split {
    fn new(p: &MpqpProblem) -> Self {
        let n = p.n();
        let h = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .map(|(i, j)| p.h[(i, j)])
            .collect();
        let (mut g, mut rows, mut bounds) = (Vec::<f64>::new(), Vec::new(), Vec::new());
        for i in 0..p.m() {
            let nz: Vec<usize> = (0..n).filter(|&j| p.g[(i, j)] != 0.0).collect();
            if nz.len() == 1 {
                bounds.push((i, nz[0], p.g[(i, nz[0])]));
                continue;
            }
            let row: Vec<f64> = (0..n).map(|j| p.g[(i, j)]).collect();
            let mirror = rows
                .iter()
                .position(|&(_, lo): &(Option<usize>, Option<usize>)| lo.is_none())
                .filter(|&k| {
                    g[k * n..(k + 1) * n]
                        .iter()
                        .zip(&row)
                        .all(|(a, b)| *a == -*b)
                });
            match mirror {
                Some(k) => rows[k].1 = Some(i),
                None => {
                    rows.push((Some(i), None));
                    g.extend(row);
                }
            }
        }
        Split {
            n,
            h,
            g,
            rows,
            bounds,
        }
    }

    /// Solves at theta (cold or warm): `z` and the iterations.
    fn solve(
        &self,
        qp: &mut QpSolver<'_, f64>,
        p: &MpqpProblem,
        theta: &DVector<f64>,
        start: Start,
    ) -> (Vec<f64>, usize) {
        let q = p.linear_term(theta);
        let rhs = p.rhs(theta);
        let u: Vec<f64> = self
            .rows
            .iter()
            .map(|r| r.0.map_or(f64::INFINITY, |i| rhs[i]))
            .collect();
        let l: Vec<f64> = self
            .rows
            .iter()
            .map(|r| r.1.map_or(f64::NEG_INFINITY, |i| -rhs[i]))
            .collect();
        let mut lb = vec![f64::NEG_INFINITY; self.n];
        let mut ub = vec![f64::INFINITY; self.n];
        for &(i, j, a) in &self.bounds {
            let v = rhs[i] / a;
            if a > 0.0 {
                ub[j] = ub[j].min(v)
            } else {
                lb[j] = lb[j].max(v)
            }
        }
        let data = QpData {
            q: q.as_slice(),
            l: &l,
            u: &u,
            lb: &lb,
            ub: &ub,
        };
        let info = qp.solve(&data, start).unwrap();
        let mut z = vec![0.0; self.n];
        qp.solution(&mut z).unwrap();
        (z, info.iterations)
    }
}

/// `p` in the variables `w` of `z = T w`, `T = I + 0.3 R` (`R` random in
/// [-1, 1]): its box rows become general rows, pairs of opposite rows
/// double-sided ones.
fn transformed(p: &MpqpProblem, seed: u64) -> MpqpProblem {
    let n = p.n();
    let mut rng = SplitMix64::seed_from_u64(seed);
    let t = DMatrix::from_fn(n, n, |i, j| {
        let r = 0.3 * (2.0 * rng.random::<f64>() - 1.0);
        if i == j { 1.0 + r } else { r }
    });
    let mut out = p.clone();
    let h = t.transpose() * &p.h * &t;
    out.h = (&h + h.transpose()) * 0.5;
    out.f_theta = &p.f_theta * &t;
    out.f = t.transpose() * &p.f;
    out.g = &p.g * &t;
    out
}

fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = 1.0 + b.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0_f64, |s, (x, y)| s.max((x - y).abs() / scale))
}

/// Checks `count` random theta: returns the worst deviation from clarabel
/// and from the explicit law (when `explicit`).
fn check(name: &str, p: &MpqpProblem, count: usize, explicit: bool) {
    let split = Split::new(p);
    let m = split.rows.len();
    let mut s = vec![0.0; scalar_len(p.n(), m)];
    let mut ix = vec![0; index_len(p.n(), m)];
    let mut qp = QpSolver::new(
        p.n(),
        m,
        &split.h,
        &split.g,
        QpSettings::default(),
        &mut s,
        &mut ix,
    )
    .unwrap();
    let settings = RefSettings {
        tolerance: 1e-11,
        max_iter: 400,
        ..RefSettings::default()
    };
    let mut reference = ReferenceSolver::new(p, settings).unwrap();
    let law = explicit.then(|| solve_mpqp(p, &Settings::default()).unwrap());
    let mut rng = SplitMix64::seed_from_u64(24);
    let (mut worst_ref, mut worst_law, mut unpolished) = (0.0_f64, 0.0_f64, 0usize);
    let (mut max_cold, mut max_warm) = (0usize, 0usize);
    for _ in 0..count {
        let theta = DVector::from_iterator(
            p.p(),
            (0..p.p())
                .map(|j| p.theta_lb[j] + (p.theta_ub[j] - p.theta_lb[j]) * rng.random::<f64>()),
        );
        let (z, cold) = split.solve(&mut qp, p, &theta, Start::Cold);
        max_cold = max_cold.max(cold);
        let r = reference.solve(&theta).unwrap();
        if r.polished {
            let dev = relative(&z, r.z.as_slice());
            assert!(
                dev <= 1e-9,
                "{name}: theta {theta:?}: {z:?} vs clarabel {:?} ({dev:e})",
                r.z
            );
            worst_ref = worst_ref.max(dev);
        } else {
            unpolished += 1;
        }
        if let Some(law) = &law {
            let ri = law.locate(theta.as_slice(), 1e-7).unwrap();
            let zl = law.regions[ri].z(theta.as_slice());
            let dev = relative(&z, zl.as_slice());
            assert!(
                dev <= 1e-9,
                "{name}: theta {theta:?}: {z:?} vs the explicit law {zl:?} ({dev:e})"
            );
            worst_law = worst_law.max(dev);
        }
        // Warm from this solution at a nearby theta (1 % of the box).
        let near = DVector::from_iterator(
            p.p(),
            (0..p.p()).map(|j| {
                let step =
                    0.01 * (p.theta_ub[j] - p.theta_lb[j]) * (2.0 * rng.random::<f64>() - 1.0);
                (theta[j] + step).clamp(p.theta_lb[j], p.theta_ub[j])
            }),
        );
        let (zw, warm) = split.solve(&mut qp, p, &near, Start::Warm);
        max_warm = max_warm.max(warm);
        let (zc, _) = split.solve(&mut qp, p, &near, Start::Cold);
        assert!(
            relative(&zw, &zc) <= 1e-9,
            "{name}: warm {zw:?} vs cold {zc:?}"
        );
    }
    assert!(
        unpolished * 100 <= count,
        "{name}: {unpolished} of {count} clarabel solutions not polished"
    );
    eprintln!(
        "{name} (n = {}, {} rows + {} bounds): {count} theta, worst relative deviation from clarabel {worst_ref:.2e} ({unpolished} unpolished skipped), from the explicit law {}; most iterations cold {max_cold}, warm (1 % step) {max_warm}",
        p.n(),
        m,
        split.bounds.len(),
        if explicit {
            format!("{worst_law:.2e}")
        } else {
            "(no law)".into()
        },
    );
}

#[test]
fn thesis_sized_tricopter_equals_clarabel_and_explicit_law() {
    check(
        "tricopter thesis-sized",
        &tricopter(ProblemSize::Thesis),
        samples(10_000),
        true,
    );
}

#[test]
fn random_thesis_sized_problems_equal_clarabel_and_explicit_law() {
    for seed in [1, 2, 3] {
        let p = kestrel_empc::testing::thesis_sized(seed);
        check(
            &format!("empc thesis_sized({seed})"),
            &p,
            samples(10_000),
            true,
        );
    }
}

#[test]
fn larger_tricopter_equals_clarabel() {
    check(
        "tricopter larger",
        &tricopter(ProblemSize::Larger),
        samples(10_000),
        false,
    );
}

#[test]
fn transformed_thesis_sized_with_general_rows_equals_clarabel_and_explicit_law() {
    let p = transformed(&tricopter(ProblemSize::Thesis), 5);
    let split = Split::new(&p);
    assert!(split.bounds.is_empty() && split.rows.iter().all(|r| r.0.is_some() && r.1.is_some()));
    check(
        "tricopter thesis-sized, z = T w (double-sided rows)",
        &p,
        samples(10_000),
        true,
    );
    let p = transformed(&kestrel_empc::testing::thesis_sized(1), 6);
    check("empc thesis_sized(1), z = T w", &p, samples(10_000), true);
}

/// The same problems in f32 ([`QpSettings::for_f32`]) against the f64
/// solution: the worst relative deviation `|z32 - z64|_inf / (1 +
/// |z64|_inf)` over the sample, bounded in docs/qp.md.
fn f32_deviation(p: &MpqpProblem, count: usize) -> f64 {
    let split = Split::new(p);
    let m = split.rows.len();
    let mut s = vec![0.0; scalar_len(p.n(), m)];
    let mut ix = vec![0; index_len(p.n(), m)];
    let mut qp = QpSolver::new(
        p.n(),
        m,
        &split.h,
        &split.g,
        QpSettings::default(),
        &mut s,
        &mut ix,
    )
    .unwrap();
    let c = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let (h32, g32) = (c(&split.h), c(&split.g));
    let mut s32 = vec![0.0_f32; scalar_len(p.n(), m)];
    let mut ix32 = vec![0; index_len(p.n(), m)];
    let mut qp32 = QpSolver::new(
        p.n(),
        m,
        &h32,
        &g32,
        QpSettings::for_f32(),
        &mut s32,
        &mut ix32,
    )
    .unwrap();
    let mut rng = SplitMix64::seed_from_u64(32);
    let mut worst = 0.0_f64;
    for _ in 0..count {
        let theta = DVector::from_iterator(
            p.p(),
            (0..p.p())
                .map(|j| p.theta_lb[j] + (p.theta_ub[j] - p.theta_lb[j]) * rng.random::<f64>()),
        );
        let (z, _) = split.solve(&mut qp, p, &theta, Start::Cold);
        // The f32 data: the f64 solver's inputs rounded.
        let q = c(p.linear_term(&theta).as_slice());
        let rhs = p.rhs(&theta);
        let u: Vec<f32> = split
            .rows
            .iter()
            .map(|r| r.0.map_or(f32::INFINITY, |i| rhs[i] as f32))
            .collect();
        let l: Vec<f32> = split
            .rows
            .iter()
            .map(|r| r.1.map_or(f32::NEG_INFINITY, |i| -rhs[i] as f32))
            .collect();
        let mut lb = vec![f32::NEG_INFINITY; p.n()];
        let mut ub = vec![f32::INFINITY; p.n()];
        for &(i, j, a) in &split.bounds {
            let v = (rhs[i] / a) as f32;
            if a > 0.0 {
                ub[j] = ub[j].min(v)
            } else {
                lb[j] = lb[j].max(v)
            }
        }
        let data = QpData {
            q: &q,
            l: &l,
            u: &u,
            lb: &lb,
            ub: &ub,
        };
        qp32.solve(&data, Start::Cold).unwrap();
        let mut z32 = vec![0.0_f32; p.n()];
        qp32.solution(&mut z32).unwrap();
        let z32: Vec<f64> = z32.iter().map(|&v| v as f64).collect();
        worst = worst.max(relative(&z32, &z));
    }
    worst
}

#[test]
fn f32_within_stated_bound() {
    for (name, p, bound) in [
        (
            "tricopter thesis-sized",
            tricopter(ProblemSize::Thesis),
            1e-4,
        ),
        (
            "empc thesis_sized(1)",
            kestrel_empc::testing::thesis_sized(1),
            1e-4,
        ),
        ("tricopter larger", tricopter(ProblemSize::Larger), 1e-4),
    ] {
        let worst = f32_deviation(&p, samples(10_000));
        eprintln!("{name}: f32 worst relative deviation from f64 {worst:.2e} (bound {bound:e})");
        assert!(worst <= bound, "{name}: {worst:e}");
    }
}
