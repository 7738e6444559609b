//! The candidate-list point location on a problem of the size
//! (1,075 regions, `tests/data/locate-1075.mpqp.json`: random 5-state,
//! 4-input MPC, N = 5, blocks [1, 4], `testing::scaled_thesis(401, 5, 2)`
//! written by `kestrel_core::formats::MpqpProblem`): the same law as
//! the solution's region lookup at 10^4 random parameters, the `u16`
//! tables equal to the `u32` ones bit for bit, `f32` tables close, the
//! flash budget, the worst-case count bounding what evaluations do, and
//! corrupted tables giving errors instead of panics.

use kestrel_core::Error;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::locate::{LocateMethod, LocateSettings, Progress, Stage, build_lists, estimate};
use kestrel_empc::{ListSlices, Outputs, Settings, evaluate_lists, solve};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

#[test]
fn lists_on_a_thousand_regions() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/locate-1075.mpqp.json"
    );
    let problem = MpqpProblem::read(std::path::Path::new(path)).unwrap();
    let solution = solve(&problem, &Settings::default()).unwrap();
    assert!(solution.regions.len() > 1000, "{}", solution.regions.len());
    let settings = LocateSettings {
        outputs: Outputs::First(4),
        ..LocateSettings::default()
    };
    let est = estimate(&problem, &solution, &settings).unwrap();
    assert_eq!(est.method, LocateMethod::Lists);
    let mut stages = Vec::new();
    let c = build_lists(&problem, &solution, &settings, &mut |p: Progress| {
        assert!(p.done <= p.total);
        if stages.last() != Some(&p.stage) {
            stages.push(p.stage);
        }
    })
    .unwrap();
    assert_eq!(
        stages,
        [Stage::Laws, Stage::Hyperplanes, Stage::Tree, Stage::Tables]
    );
    let s = &c.stats;
    assert_eq!(s.distinct_laws, est.distinct_laws);
    assert!(s.fits_u16 && s.bytes_f32 < 256 * 1024, "{s:?}");
    let narrow = c.tables.narrow().unwrap();
    let single = narrow.cast::<f32>();
    let (t64, t32) = (narrow.tables(), single.tables());
    let p = solution.p;
    let mut rng = SplitMix64::seed_from_u64(23);
    let (mut z, mut zw, mut z32) = (vec![0.0; 4], vec![0.0; 4], vec![0.0f32; 4]);
    let (mut scratch, mut scratch32) = (vec![0.0; p], vec![0.0f32; p]);
    let mut inside = 0;
    for _ in 0..10_000 {
        // About 6 in 10 points outside the box (each coordinate 1 in 11).
        let theta: Vec<f64> = (0..p)
            .map(|j| {
                let (lo, hi) = (solution.theta_lb[j], solution.theta_ub[j]);
                lo + (hi - lo) * (1.1 * rng.random::<f64>() - 0.05)
            })
            .collect();
        let e = evaluate_lists(&t64, &theta, &mut scratch, &mut z).unwrap();
        let ew = c.tables.evaluate_f64(&theta, &mut zw).unwrap();
        assert_eq!((z.as_slice(), u32::from(e.law)), (zw.as_slice(), ew.law));
        let hyperplanes = usize::from(e.steps) + usize::from(e.tests);
        assert!(hyperplanes <= s.worst_case_hyperplanes);
        let th32: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        evaluate_lists(&t32, &th32, &mut scratch32, &mut z32).unwrap();
        for (a, b) in z32.iter().zip(&z) {
            assert!((f64::from(*a) - b).abs() <= 1e-3 * (1.0 + b.abs()));
        }
        match solution.first_outputs_at(&theta, 4) {
            Some(want) => {
                assert!(!e.outside);
                for (a, b) in z.iter().zip(&want) {
                    assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()), "{z:?} {want:?}");
                }
                inside += 1;
            }
            None => assert!(e.outside, "{theta:?}"),
        }
    }
    assert!(inside > 3_000, "{inside}");
    // Corrupted tables: errors, not panics.
    let th = vec![0.0; p];
    let bad_node = [[u16::MAX - 1, 0, 0]];
    let broken = [
        ListSlices {
            root: 0,
            nodes: &bad_node,
            ..t64
        },
        ListSlices {
            entries: &[],
            ..t64
        },
        ListSlices {
            rows: &narrow.rows[..10],
            ..t64
        },
        ListSlices {
            region_start: &narrow.region_start[..1],
            ..t64
        },
    ];
    for b in &broken {
        assert_eq!(
            evaluate_lists(b, &th, &mut scratch, &mut z),
            Err(Error::OutOfRange)
        );
    }
    assert!(matches!(
        evaluate_lists(&t64, &th[..p - 1], &mut scratch, &mut z),
        Err(Error::DimensionMismatch { .. })
    ));
    assert_eq!(
        evaluate_lists(&t64, &[f64::NAN; 9], &mut scratch, &mut z),
        Err(Error::NonFinite)
    );
}
