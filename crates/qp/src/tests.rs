//! Exact references (box-QP enumeration), the defined errors, degenerate
//! (dependent) constraints.
// Reference computations index dense matrices the textbook way.
#![allow(clippy::needless_range_loop)]

use crate::tests_kkt::{RandomQp, solve};
use crate::{
    ActiveConstraint, QpData, QpError, QpSettings, QpSolver, Side, Start, index_len, scalar_len,
};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// Solves `A x = b` (`k x k`, row-major) by Gaussian elimination with
/// partial pivoting.
fn gauss(mut a: Vec<f64>, mut b: Vec<f64>, k: usize) -> Vec<f64> {
    for c in 0..k {
        let p = (c..k)
            .max_by(|&i, &j| a[i * k + c].abs().total_cmp(&a[j * k + c].abs()))
            .unwrap();
        for j in 0..k {
            a.swap(c * k + j, p * k + j);
        }
        b.swap(c, p);
        for r in c + 1..k {
            let f = a[r * k + c] / a[c * k + c];
            for j in c..k {
                a[r * k + j] -= f * a[c * k + j];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; k];
    for r in (0..k).rev() {
        let s: f64 = (r + 1..k).map(|j| a[r * k + j] * x[j]).sum();
        x[r] = (b[r] - s) / a[r * k + r];
    }
    x
}

/// The box QP's optimum by enumerating all `3^n` faces (each variable
/// free, at its lower or at its upper bound): the feasible face optimum
/// with the least objective.
fn enumerate_box(n: usize, h: &[f64], q: &[f64], lb: &[f64], ub: &[f64]) -> Vec<f64> {
    let mut best: Option<(f64, Vec<f64>)> = None;
    for code in 0..3usize.pow(n as u32) {
        let mut z = vec![0.0; n];
        let mut free = Vec::new();
        let mut c = code;
        for i in 0..n {
            match c % 3 {
                0 => free.push(i),
                1 => z[i] = lb[i],
                _ => z[i] = ub[i],
            }
            c /= 3;
        }
        let k = free.len();
        let a: Vec<f64> = free
            .iter()
            .flat_map(|&i| free.iter().map(move |&j| h[i * n + j]))
            .collect();
        let b: Vec<f64> = free
            .iter()
            .map(|&i| {
                -q[i]
                    - (0..n)
                        .filter(|j| !free.contains(j))
                        .map(|j| h[i * n + j] * z[j])
                        .sum::<f64>()
            })
            .collect();
        for (&i, v) in free.iter().zip(gauss(a, b, k)) {
            z[i] = v;
        }
        if (0..n).any(|i| z[i] < lb[i] - 1e-12 || z[i] > ub[i] + 1e-12) {
            continue;
        }
        let obj: f64 = (0..n)
            .map(|i| q[i] * z[i] + 0.5 * z[i] * (0..n).map(|j| h[i * n + j] * z[j]).sum::<f64>())
            .sum();
        if best.as_ref().is_none_or(|(o, _)| obj < *o) {
            best = Some((obj, z));
        }
    }
    best.unwrap().1
}

#[test]
fn box_qps_equal_enumeration() {
    let mut rng = SplitMix64::seed_from_u64(7);
    for trial in 0..400 {
        let n = 1 + trial % 5;
        let mut qp = RandomQp::new(trial as u64 + 30_000, n, 0);
        for i in 0..n {
            qp.lb[i] = -rng.random::<f64>();
            qp.ub[i] = rng.random::<f64>();
        }
        let (z, _, _) = solve(&qp, QpSettings::default()).unwrap();
        let exact = enumerate_box(n, &qp.h, &qp.q, &qp.lb, &qp.ub);
        for (a, b) in z.iter().zip(&exact) {
            assert!(
                (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
                "trial {trial}: {z:?} vs {exact:?}"
            );
        }
    }
}

fn solver_2x2<'w>(
    g: &[f64],
    m: usize,
    s: &'w mut [f64],
    ix: &'w mut [usize],
    settings: QpSettings,
) -> QpSolver<'w, f64> {
    QpSolver::new(2, m, &[2.0, 0.5, 0.5, 1.0], g, settings, s, ix).unwrap()
}

#[test]
fn infeasible_problems_are_detected() {
    let mut s = vec![0.0; scalar_len(2, 2)];
    let mut ix = vec![0; index_len(2, 2)];
    // Contradictory rows: z0 <= -1 and z0 >= 1.
    let mut qp = solver_2x2(
        &[1.0, 0.0, 1.0, 0.0],
        2,
        &mut s,
        &mut ix,
        QpSettings::default(),
    );
    let inf = f64::INFINITY;
    let data = QpData {
        q: &[0.0, 0.0],
        l: &[-inf, 1.0],
        u: &[-1.0, inf],
        lb: &[-inf; 2],
        ub: &[inf; 2],
    };
    assert_eq!(qp.solve(&data, Start::Cold), Err(QpError::Infeasible));
    // A row against the bounds: z0 + z1 >= 3 with z <= 1.
    let mut s = vec![0.0; scalar_len(2, 1)];
    let mut ix = vec![0; index_len(2, 1)];
    let mut qp = solver_2x2(&[1.0, 1.0], 1, &mut s, &mut ix, QpSettings::default());
    let data = QpData {
        q: &[1.0, 1.0],
        l: &[3.0],
        u: &[inf],
        lb: &[-inf; 2],
        ub: &[1.0, 1.0],
    };
    assert_eq!(qp.solve(&data, Start::Cold), Err(QpError::Infeasible));
    // The same row made feasible: z = (1, 1) exactly.
    let data = QpData { l: &[2.0], ..data };
    qp.solve(&data, Start::Cold).unwrap();
    let mut z = [0.0; 2];
    qp.solution(&mut z).unwrap();
    assert!((z[0] - 1.0).abs() < 1e-12 && (z[1] - 1.0).abs() < 1e-12);
}

#[test]
fn dependent_constraints_are_resolved() {
    // The same row three times (scaled) and an equality: the dependent
    // entries take the singular step; the KKT point is still exact.
    let g = [1.0, 1.0, 2.0, 2.0, -1.0, -1.0, 1.0, -1.0];
    let mut s = vec![0.0; scalar_len(2, 4)];
    let mut ix = vec![0; index_len(2, 4)];
    let mut qp = solver_2x2(&g, 4, &mut s, &mut ix, QpSettings::default());
    let inf = f64::INFINITY;
    let data = QpData {
        q: &[-4.0, -4.0],
        l: &[-inf, -inf, -1.0, 0.25],
        u: &[1.0, 2.0, inf, 0.25],
        lb: &[-inf; 2],
        ub: &[inf; 2],
    };
    qp.solve(&data, Start::Cold).unwrap();
    let mut z = [0.0; 2];
    qp.solution(&mut z).unwrap();
    // z0 + z1 = 1, z0 - z1 = 0.25.
    assert!(
        (z[0] - 0.625).abs() < 1e-12 && (z[1] - 0.375).abs() < 1e-12,
        "{z:?}"
    );
    let mut mu = [0.0; 6];
    qp.multipliers(&mut mu).unwrap();
    // Stationarity with the original data.
    let r0 = 2.0 * z[0] + 0.5 * z[1] - 4.0 + mu[0] + 2.0 * mu[1] - mu[2] + mu[3] + mu[4];
    let r1 = 0.5 * z[0] + z[1] - 4.0 + mu[0] + 2.0 * mu[1] - mu[2] - mu[3] + mu[5];
    assert!(r0.abs() < 1e-12 && r1.abs() < 1e-12, "{r0} {r1} {mu:?}");
    assert!(mu[0] >= 0.0 && mu[1] >= 0.0 && mu[2] <= 0.0);
}

#[test]
fn iteration_cap_is_an_error() {
    let qp = RandomQp::new(3, 8, 12);
    let (_, _, needed) = solve(&qp, QpSettings::default()).unwrap();
    assert!(needed >= 2);
    let capped = QpSettings {
        max_iterations: needed - 1,
        ..QpSettings::default()
    };
    assert_eq!(solve(&qp, capped).unwrap_err(), QpError::IterationLimit);
    let exact = QpSettings {
        max_iterations: needed,
        ..QpSettings::default()
    };
    assert_eq!(solve(&qp, exact).unwrap().2, needed);
}

#[test]
fn sizes_and_inputs_are_checked() {
    let h = [1.0, 0.0, 0.0, 1.0];
    let mut s = vec![0.0; scalar_len(2, 1)];
    let mut ix = vec![0; index_len(2, 1)];
    let d = QpSettings::default();
    let short = &mut vec![0.0; scalar_len(2, 1) - 1];
    assert!(matches!(
        QpSolver::new(2, 1, &h, &[1.0, 1.0], d, short, &mut ix),
        Err(QpError::Dimension { .. })
    ));
    assert!(matches!(
        QpSolver::new(2, 1, &h, &[1.0], d, &mut s, &mut ix),
        Err(QpError::Dimension { .. })
    ));
    assert!(matches!(
        QpSolver::new(0, 0, &[], &[], d, &mut s, &mut ix),
        Err(QpError::Dimension { .. })
    ));
    // Sizes beyond the address space saturate and are refused.
    assert_eq!(scalar_len(usize::MAX / 2, 3), usize::MAX);
    assert!(matches!(
        QpSolver::new(usize::MAX / 2, 3, &h, &[], d, &mut s, &mut ix),
        Err(QpError::Dimension { .. })
    ));
    let indefinite = [1.0, 2.0, 2.0, 1.0];
    assert_eq!(
        QpSolver::new(2, 1, &indefinite, &[1.0, 1.0], d, &mut s, &mut ix).unwrap_err(),
        QpError::NotPositiveDefinite
    );
    assert_eq!(
        QpSolver::new(
            2,
            1,
            &[f64::NAN, 0.0, 0.0, 1.0],
            &[1.0, 1.0],
            d,
            &mut s,
            &mut ix
        )
        .unwrap_err(),
        QpError::NonFinite
    );
    let bad = QpSettings {
        max_iterations: 0,
        ..d
    };
    assert_eq!(bad.validate(), Err(QpError::InvalidSettings));
    assert_eq!(
        QpSettings {
            primal_tol: f64::NAN,
            ..d
        }
        .validate(),
        Err(QpError::InvalidSettings)
    );
    assert_eq!(
        QpSolver::new(2, 1, &h, &[1.0, 1.0], bad, &mut s, &mut ix).unwrap_err(),
        QpError::InvalidSettings
    );
    let mut qp = QpSolver::new(2, 1, &h, &[1.0, 1.0], d, &mut s, &mut ix).unwrap();
    let inf = f64::INFINITY;
    let ok = QpData {
        q: &[0.0, 0.0],
        l: &[-1.0],
        u: &[1.0],
        lb: &[-inf; 2],
        ub: &[inf; 2],
    };
    assert!(matches!(
        qp.solve(&QpData { q: &[0.0], ..ok }, Start::Cold),
        Err(QpError::Dimension { .. })
    ));
    assert_eq!(
        qp.solve(&QpData { l: &[2.0], ..ok }, Start::Cold),
        Err(QpError::InvalidBounds)
    );
    assert_eq!(
        qp.solve(
            &QpData {
                u: &[f64::NAN],
                ..ok
            },
            Start::Cold
        ),
        Err(QpError::NonFinite)
    );
    assert_eq!(
        qp.solve(
            &QpData {
                q: &[inf, 0.0],
                ..ok
            },
            Start::Cold
        ),
        Err(QpError::NonFinite)
    );
    let a = |index, side| ActiveConstraint { index, side };
    assert_eq!(
        qp.set_active_set(&[a(3, Side::Upper)]),
        Err(QpError::InvalidActiveSet)
    );
    assert_eq!(
        qp.set_active_set(&[a(0, Side::Upper), a(0, Side::Lower)]),
        Err(QpError::InvalidActiveSet)
    );
    assert_eq!(
        qp.set_active_set(&[a(0, Side::Upper), a(1, Side::Lower), a(2, Side::Lower)]),
        Err(QpError::InvalidActiveSet)
    );
    // A warm set with a wrong-sign member is repaired: one removal.
    qp.set_active_set(&[a(0, Side::Upper)]).unwrap();
    let info = qp.solve(&ok, Start::Warm).unwrap();
    assert_eq!((info.iterations, info.active), (1, 0));
    let mut z = [1.0; 2];
    qp.solution(&mut z).unwrap();
    assert_eq!(z, [0.0, 0.0]);
    assert!(qp.solution(&mut [0.0; 3]).is_err() && qp.multipliers(&mut [0.0; 2]).is_err());
}

#[test]
fn errors_map_to_core_errors() {
    let all = [
        QpError::Dimension {
            expected: 2,
            found: 1,
        },
        QpError::NonFinite,
        QpError::NotPositiveDefinite,
        QpError::InvalidBounds,
        QpError::InvalidSettings,
        QpError::InvalidActiveSet,
        QpError::Infeasible,
        QpError::IterationLimit,
    ];
    let core: Vec<kestrel_core::Error> = all.iter().map(|&e| e.into()).collect();
    assert_eq!(
        core[0],
        kestrel_core::Error::DimensionMismatch {
            expected: 2,
            found: 1
        }
    );
    assert_eq!(core[6], kestrel_core::Error::Infeasible);
    assert_eq!(core[7], kestrel_core::Error::NotConverged);
    for e in all {
        assert!(!format!("{e}").is_empty());
    }
}
