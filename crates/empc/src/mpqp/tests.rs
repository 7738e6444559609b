//! Tests of the solver's internals (its results are tested in `tests/`).

use crate::lp::{LpStatus, LpWorkspace};
use crate::mpqp::prepare::prepare;
use crate::mpqp::settings::Settings;
use crate::rng::Rng;
use crate::testing;

/// The propagated box contains the polytope: for random polytopes
/// (random unit rows around the box centre, within the thesis-sized
/// problem's parameter box) every coordinate's maximum and minimum,
/// from an LP, lie inside it; and it is tighter than the parameter box.
#[test]
fn implied_box_contains_the_polytope() {
    let prep = prepare(&testing::thesis_sized(1), &Settings::default()).unwrap();
    let p = prep.p;
    let mut rng = Rng::new(21);
    let mut lp = LpWorkspace::default();
    let mut tighter = 0;
    for _ in 0..200 {
        let rows = 2 + (rng.next_u64() % 14) as usize;
        let centre: Vec<f64> = (0..p)
            .map(|j| 0.5 * (prep.theta_lb[j] + prep.theta_ub[j]))
            .collect();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..rows {
            let mut r: Vec<f64> = (0..p).map(|_| rng.sym()).collect();
            if rng.next_u64().is_multiple_of(3) {
                let keep = (rng.next_u64() % p as u64) as usize;
                for (j, v) in r.iter_mut().enumerate() {
                    if j != keep && rng.next_u64().is_multiple_of(2) {
                        *v = 0.0;
                    }
                }
            }
            let n = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            r.iter_mut().for_each(|v| *v /= n);
            b.push(crate::lp::dot(&r, &centre) + 0.05 + 0.5 * rng.sym().abs());
            a.extend(r);
        }
        let (lo, hi) = prep.implied_box(&a, &b);
        // The LP over the rows and the box.
        let (mut la, mut lb) = (a.clone(), b.clone());
        for j in 0..p {
            for (s, v) in [(1.0, prep.theta_ub[j]), (-1.0, -prep.theta_lb[j])] {
                la.extend((0..p).map(|t| if t == j { s } else { 0.0 }));
                lb.push(v);
            }
        }
        for j in 0..p {
            let e: Vec<f64> = (0..p).map(|t| if t == j { 1.0 } else { 0.0 }).collect();
            let (st, top) = lp.maximize_from(&e, &la, &lb, &centre);
            assert_eq!(st, LpStatus::Optimal);
            assert!(top <= hi[j] + 1e-9, "max {top} above the box's {}", hi[j]);
            let ne: Vec<f64> = e.iter().map(|v| -v).collect();
            let (st, bot) = lp.maximize_from(&ne, &la, &lb, &centre);
            assert_eq!(st, LpStatus::Optimal);
            assert!(
                -bot >= lo[j] - 1e-9,
                "min {} below the box's {}",
                -bot,
                lo[j]
            );
            if hi[j] < prep.theta_ub[j] - 1e-6 || lo[j] > prep.theta_lb[j] + 1e-6 {
                tighter += 1;
            }
        }
    }
    assert!(tighter > 20, "{tighter}");
}

/// A degenerate problem (2,312 probe QPs for 480 regions): the waves give
/// the same regions in the same order, bit for bit, on one thread and on
/// several (with the `parallel` feature), and no active set's region is
/// computed twice.
#[test]
fn waves_are_deterministic_and_compute_each_set_once() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/wide-tree.mpqp.json"
    );
    let prob = kestrel_core::formats::MpqpProblem::read(std::path::Path::new(path)).unwrap();
    let run = |parallel| {
        crate::mpqp::solve(
            &prob,
            &Settings {
                parallel,
                ..Settings::default()
            },
        )
        .unwrap()
    };
    let (one, many) = (run(false), run(true));
    assert_eq!(one.regions.len(), 480);
    assert_eq!(one.regions, many.regions);
    assert_eq!(one.stats.lps, many.stats.lps);
    let s = &one.stats;
    assert!(s.fallback_qps > 2000, "{s:?}");
    // Each set once: here every set tested is a region or a guessed set
    // without one (the one-phase waves tested 3,631 sets for the same 480
    // regions and 867 region-less guesses).
    assert_eq!(
        s.active_sets_tested,
        one.regions.len() + s.discarded,
        "{s:?}"
    );
    let mut sets: Vec<&Vec<usize>> = one.regions.iter().map(|r| &r.active_set).collect();
    sets.sort();
    sets.dedup();
    assert_eq!(sets.len(), 480);
}
