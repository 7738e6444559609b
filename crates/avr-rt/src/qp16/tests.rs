//! The fixed-point solver against kestrel-qp's f64 one on the same
//! problems: the tricopter thesis-sized (`n = 4`, 9 parameters) and larger
//! (`n = 16`) problems (`tests/data/qp16-*.mpqp.json`, written by `kestrel
//! mpc --model models/tricopter-blackbox-5.json --tricopter --q1 2000 --q2
//! 0.01 --horizon 2 --blocks 2` and `--horizon 10 --blocks 1,1,2,6`) and
//! random box QPs.

use super::*;
use kestrel_core::formats::MpqpProblem;
use kestrel_qp::{QpData, QpSettings, QpSolver, Side, Start, index_len, scalar_len};

pub(super) struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The f64 reference: kestrel-qp on the box form.
pub(super) struct Reference {
    n: usize,
    p: usize,
    h: Vec<f64>,
    q: Vec<f64>,
    q0: Vec<f64>,
    lbt: Vec<f64>,
    lb0: Vec<f64>,
    ubt: Vec<f64>,
    ub0: Vec<f64>,
    pub(super) theta_lb: Vec<f64>,
    pub(super) theta_ub: Vec<f64>,
}

/// One f64 solve: solution, sorted active set `(variable, upper)`,
/// iterations.
pub(super) type Answer = (Vec<f64>, Vec<(usize, bool)>, usize);

impl Reference {
    pub(super) fn new(p: &MpqpProblem) -> Self {
        let (h, q, q0, lbt, lb0, ubt, ub0) = box_form(p).unwrap();
        Reference {
            n: p.n(),
            p: p.p(),
            h,
            q,
            q0,
            lbt,
            lb0,
            ubt,
            ub0,
            theta_lb: p.theta_lb.iter().copied().collect(),
            theta_ub: p.theta_ub.iter().copied().collect(),
        }
    }

    fn affine(&self, rows: &[f64], c0: &[f64], th: &[f64]) -> Vec<f64> {
        (0..self.n)
            .map(|i| {
                let r = &rows[i * self.p..(i + 1) * self.p];
                r.iter().zip(th).fold(c0[i], |a, (g, t)| a + g * t)
            })
            .collect()
    }

    pub(super) fn solve(&self, th: &[f64]) -> Answer {
        let n = self.n;
        let (mut s, mut ix) = (vec![0.0; scalar_len(n, 0)], vec![0; index_len(n, 0)]);
        let mut qp =
            QpSolver::new(n, 0, &self.h, &[], QpSettings::default(), &mut s, &mut ix).unwrap();
        let q = self.affine(&self.q, &self.q0, th);
        let lb = self.affine(&self.lbt, &self.lb0, th);
        let ub = self.affine(&self.ubt, &self.ub0, th);
        let data = QpData {
            q: &q,
            l: &[],
            u: &[],
            lb: &lb,
            ub: &ub,
        };
        let info = qp.solve(&data, Start::Cold).unwrap();
        let mut z = vec![0.0; n];
        qp.solution(&mut z).unwrap();
        let mut set: Vec<(usize, bool)> = qp
            .active_set()
            .map(|a| (a.index, a.side == Side::Upper))
            .collect();
        set.sort();
        (z, set, info.iterations)
    }

    pub(super) fn random_theta(&self, rng: &mut Rng) -> Vec<f64> {
        (0..self.p)
            .map(|j| self.theta_lb[j] + (self.theta_ub[j] - self.theta_lb[j]) * rng.uniform())
            .collect()
    }
}

pub(super) fn fixture(name: &str) -> MpqpProblem {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    MpqpProblem::read(&path).unwrap()
}

/// Compares at `count` random theta; returns (mismatched active sets,
/// mismatched iteration counts, max |z16 - z64| in problem units, max
/// iterations).
fn compare<const N: usize, const P: usize>(
    p: &MpqpProblem,
    count: usize,
) -> (usize, usize, f64, u16) {
    let (t, scaling) = Qp16Tables::<N, P>::from_mpqp(p, Qp16Settings::default()).unwrap();
    let r = Reference::new(p);
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut s = Qp16Solver::<N>::new();
    let (mut sets, mut iters, mut err, mut most) = (0, 0, 0.0f64, 0);
    let (mut sets_differ, mut set_err) = (0, 0.0f64);
    // The per-set kernel where its tables are small (N = 4).
    let mut per_set = t
        .set_tables::<16, 128>()
        .ok()
        .map(|st| (st, Qp16SetSolver::<N>::new()));
    for _ in 0..count {
        let th = r.random_theta(&mut rng);
        let tq = theta_q16::<P>(&th);
        // The f64 solver at the theta the AVR sees (Q15.16 values).
        let th: Vec<f64> = tq.iter().map(|&v| v as f64 / 65_536.0).collect();
        let (z, set, it) = r.solve(&th);
        let info = s.solve(&t, &tq, Qp16Start::Cold).unwrap();
        if let Some((st, ss)) = per_set.as_mut() {
            // The per-set kernel: the same decisions, its own rounding.
            let i2 = ss.solve(&t, st, &tq, Qp16Start::Cold).unwrap();
            let mut g2: Vec<(usize, bool)> =
                ss.active_set().map(|(j, u)| (j as usize, u)).collect();
            g2.sort();
            sets_differ += usize::from(g2 != set || i2.iterations as usize != it);
            if g2 == set {
                for (w, zr) in ss.solution().iter().zip(&z) {
                    set_err = set_err.max((t.to_problem_f64(*w) - zr).abs());
                }
            }
        }
        // The updated factor against P_AA formed from scratch.
        assert!(s.factor_residual(&t) < 1e-5, "{}", s.factor_residual(&t));
        let mut got: Vec<(usize, bool)> = s.active_set().map(|(j, u)| (j as usize, u)).collect();
        got.sort();
        sets += usize::from(got != set);
        iters += usize::from(info.iterations as usize != it);
        most = most.max(info.iterations);
        if got == set {
            for (w, zr) in s.solution().iter().zip(&z) {
                err = err.max((t.to_problem_f64(*w) - zr).abs());
            }
        }
    }
    println!(
        "qp16 n = {N}: scaling {scaling:?}; {count} theta: {sets} active sets and {iters} iteration counts differ, max |z - z_f64| {err:.3e}, max iterations {most}; per-set kernel: {sets_differ} differ, max |z - z_f64| {set_err:.3e}"
    );
    assert_eq!(sets_differ, 0);
    (sets, iters, err, most)
}

fn samples(default: usize) -> usize {
    std::env::var("KESTREL_QP_SAMPLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

#[test]
fn thesis_sized_equals_kestrel_qp_f64() {
    let p = fixture("qp16-thesis.mpqp.json");
    let (sets, iters, err, _) = compare::<4, 9>(&p, samples(10_000));
    assert_eq!((sets, iters), (0, 0));
    // Pulses in us: the stated bound (docs/avr-qp.md).
    assert!(err < 2e-3, "{err}");
}

#[test]
fn larger_equals_kestrel_qp_f64() {
    let p = fixture("qp16-larger.mpqp.json");
    let (sets, iters, err, _) = compare::<16, 9>(&p, samples(2_000));
    assert_eq!((sets, iters), (0, 0));
    assert!(err < 0.1, "{err}");
}

/// Random strictly convex box QPs (`H = A A' + 0.2 I`, random bounds
/// affine in theta), 5 variables, 3 parameters.
#[test]
fn random_box_qps_equal_kestrel_qp_f64() {
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let (mut total, mut differ) = (0, 0);
    for _ in 0..40 {
        const N: usize = 5;
        const P: usize = 3;
        let a: Vec<f64> = (0..N * N).map(|_| rng.uniform() * 2.0 - 1.0).collect();
        let mut h = vec![0.0; N * N];
        for i in 0..N {
            for j in 0..N {
                h[i * N + j] = (0..N).map(|k| a[i * N + k] * a[j * N + k]).sum::<f64>()
                    + if i == j { 0.2 } else { 0.0 };
            }
        }
        let q: Vec<f64> = (0..N * P).map(|_| 4.0 * rng.uniform() - 2.0).collect();
        let q0: Vec<f64> = (0..N).map(|_| rng.uniform() - 0.5).collect();
        let lbt: Vec<f64> = (0..N * P).map(|_| 0.2 * rng.uniform() - 0.1).collect();
        let ubt = lbt.clone();
        let lb0: Vec<f64> = (0..N).map(|_| -0.5 - rng.uniform()).collect();
        let ub0: Vec<f64> = (0..N).map(|_| 0.5 + rng.uniform()).collect();
        let (tl, tu) = (vec![-1.0; P], vec![1.0; P]);
        let qp = BoxQp {
            h: &h,
            q_theta: &q,
            q0: &q0,
            lb_theta: &lbt,
            lb0: &lb0,
            ub_theta: &ubt,
            ub0: &ub0,
            theta_lb: &tl,
            theta_ub: &tu,
        };
        let (t, _) = Qp16Tables::<N, P>::from_matrices(&qp, Qp16Settings::default()).unwrap();
        let r = Reference {
            n: N,
            p: P,
            h: h.clone(),
            q: q.clone(),
            q0: q0.clone(),
            lbt: lbt.clone(),
            lb0: lb0.clone(),
            ubt: ubt.clone(),
            ub0: ub0.clone(),
            theta_lb: tl.clone(),
            theta_ub: tu.clone(),
        };
        let mut s = Qp16Solver::<N>::new();
        for _ in 0..50 {
            let tq = theta_q16::<P>(&r.random_theta(&mut rng));
            let th: Vec<f64> = tq.iter().map(|&v| v as f64 / 65_536.0).collect();
            let (z, set, it) = r.solve(&th);
            let info = s.solve(&t, &tq, Qp16Start::Cold).unwrap();
            let mut got: Vec<(usize, bool)> =
                s.active_set().map(|(j, u)| (j as usize, u)).collect();
            got.sort();
            total += 1;
            if got != set || info.iterations as usize != it {
                differ += 1;
                continue;
            }
            for (w, zr) in s.solution().iter().zip(&z) {
                let e = (t.to_problem_f64(*w) - zr).abs();
                assert!(e < 1e-3 * (1.0 + zr.abs()), "{e}");
            }
        }
    }
    // Near-ties (two violations within the rounding) may decide otherwise.
    assert!(differ * 200 <= total, "{differ} of {total} differ");
}

#[test]
fn warm_start_from_the_optimal_set_makes_no_change() {
    let p = fixture("qp16-thesis.mpqp.json");
    let (t, _) = Qp16Tables::<4, 9>::from_mpqp(&p, Qp16Settings::default()).unwrap();
    let r = Reference::new(&p);
    let mut rng = Rng(7);
    let mut s = Qp16Solver::<4>::new();
    for _ in 0..500 {
        let tq = theta_q16::<9>(&r.random_theta(&mut rng));
        s.solve(&t, &tq, Qp16Start::Cold).unwrap();
        let cold = *s.solution();
        let info = s.solve(&t, &tq, Qp16Start::Warm).unwrap();
        assert_eq!(info.iterations, 0);
        assert_eq!(*s.solution(), cold);
    }
}

#[test]
fn errors_and_fallback() {
    let p = fixture("qp16-thesis.mpqp.json");
    let settings = Qp16Settings {
        max_iterations: 1,
        ..Qp16Settings::default()
    };
    let (t, _) = Qp16Tables::<4, 9>::from_mpqp(&p, settings).unwrap();
    let r = Reference::new(&p);
    let mut rng = Rng(11);
    let mut s = Qp16Solver::<4>::new();
    let mut capped = 0;
    for _ in 0..200 {
        let th = r.random_theta(&mut rng);
        let tq = theta_q16::<9>(&th);
        if let Err(e) = s.solve(&t, &tq, Qp16Start::Cold) {
            assert_eq!(e, Qp16Error::IterationLimit);
            capped += 1;
            let (_, set, it) = r.solve(&th);
            assert!(it > 1 && !set.is_empty());
            let u = s.fallback();
            for (i, v) in u.iter().enumerate() {
                assert!(t.lb[i].eval(&tq) <= *v && *v <= t.ub[i].eval(&tq));
            }
        }
    }
    assert!(capped > 0);
    // An empty box.
    let mut bad = t;
    bad.lb[0] = Row32::constant(i32::MAX - 1);
    assert_eq!(
        s.solve(&bad, &[0; 9], Qp16Start::Cold),
        Err(Qp16Error::InvalidBounds)
    );
}

mod never_panics {
    use super::*;
    use crate::mac::Row16;
    use proptest::prelude::*;

    fn row32(v: &[i32], s: u8) -> Row32<3> {
        Row32 {
            c: [v[0], v[1], v[2]],
            c0: v[3],
            shift: s,
            start: (v[4] & 7) as u8,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Arbitrary tables, parameters, caps and starts (overflow checks
        /// on in tests): every solve of both kernels returns a result or an
        /// error, and the fallback stays in consistent bounds.
        #[test]
        fn on_arbitrary_tables(
            v in proptest::collection::vec(any::<i32>(), 120),
            bits in proptest::collection::vec(any::<u8>(), 12),
            theta in proptest::collection::vec(any::<i32>(), 3),
        ) {
            let b = |i: usize| bits[i];
            let t = Qp16Tables::<2, 3> {
                hinv: [[v[0], v[1]], [v[2], v[3]]],
                unc_hi: [Row16::new([v[4] as i16, v[5] as i16, v[6] as i16], b(0), b(1) & 3),
                         Row16::new([v[7] as i16, v[8] as i16, v[9] as i16], b(2), b(3) & 3)],
                unc_lo: [Row16::new([v[10] as i16, v[11] as i16, v[12] as i16], b(4), 0),
                         Row16::new([v[13] as i16, v[14] as i16, v[15] as i16], b(5), 0)],
                unc0: [v[16], v[17]],
                lb: [row32(&v[20..25], b(6)), row32(&v[25..30], b(7))],
                ub: [row32(&v[30..35], b(8)), row32(&v[35..40], b(9))],
                var_shift: b(10) as i8,
                obj_shift: 0,
                p_bits: b(11),
                l_bits: b(0),
                nu_bits: b(1),
                pivot_bits: b(2),
                primal_tol: v[40],
                dual_tol: v[41],
                max_iterations: (v[42] & 15) as u16,
            };
            let sets = Qp16SetTables::<2, 4, 8> {
                offset: [0, 0, 1, 2],
                data: [v[50], v[51], v[52], v[53], v[54], v[55], v[56], v[57]],
                minv_bits: b(3),
                w_bits: b(3),
            };
            let th = [theta[0], theta[1], theta[2]];
            let mut s = Qp16Solver::<2>::new();
            let mut ps = Qp16SetSolver::<2>::new();
            for start in [Qp16Start::Cold, Qp16Start::Warm, Qp16Start::Warm] {
                let r = s.solve(&t, &th, start);
                let rp = ps.solve(&t, &sets, &th, start);
                for (res, fb) in [(r.is_err(), s.fallback()), (rp.is_err(), ps.fallback())] {
                    if res {
                        for (i, f) in fb.iter().enumerate() {
                            let (lo, hi) = (t.lb[i].eval(&th), t.ub[i].eval(&th));
                            if lo <= hi {
                                prop_assert!(lo <= *f && *f <= hi);
                            }
                        }
                    }
                }
            }
        }
    }
}
