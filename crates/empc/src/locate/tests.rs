//! The candidate lists against the solution's own region lookup.

use crate::locate::{LocateMethod, LocateSettings, build_lists, build_locator, estimate};
use crate::testing::thesis_sized;
use crate::tree::Outputs;
use crate::{Settings, solve};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

#[test]
fn lists_answer_as_the_region_lookup() {
    let problem = thesis_sized(3);
    let solution = solve(&problem, &Settings::default()).unwrap();
    let settings = LocateSettings {
        outputs: Outputs::First(4),
        leaf_regions: 3,
        ..LocateSettings::default()
    };
    let mut reports = 0;
    let c = build_lists(&problem, &solution, &settings, &mut |_| reports += 1).unwrap();
    assert!(reports >= 4);
    let narrow = c.tables.narrow().unwrap();
    let mut rng = SplitMix64::seed_from_u64(11);
    let p = solution.p;
    let (mut z, mut z16) = (vec![0.0; 4], vec![0.0; 4]);
    let mut checked = 0;
    for _ in 0..10_000 {
        let theta: Vec<f64> = (0..p)
            .map(|j| {
                let (lo, hi) = (solution.theta_lb[j], solution.theta_ub[j]);
                lo + (hi - lo) * rng.random::<f64>()
            })
            .collect();
        let e = c.tables.evaluate_f64(&theta, &mut z).unwrap();
        narrow.evaluate_f64(&theta, &mut z16).unwrap();
        assert_eq!(z, z16);
        if let Some(want) = solution.first_outputs_at(&theta, 4) {
            assert!(!e.outside);
            for (a, b) in z.iter().zip(&want) {
                assert!(
                    (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
                    "{z:?} {want:?} at {theta:?}"
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 1000, "{checked} {:?}", c.stats);
    eprintln!("{:?}", c.stats);
    assert_eq!(c.stats.entries, c.tables.entries.len());
    assert!(c.stats.worst_case_hyperplanes >= c.stats.depth);
    let est = estimate(&problem, &solution, &settings).unwrap();
    assert_eq!(est.method, LocateMethod::Tree);
    let auto = build_locator(&problem, &solution, &settings, &mut |_| {}).unwrap();
    assert_eq!(auto.method(), LocateMethod::Tree);
}

#[test]
fn lists_json_round_trip_and_checks() {
    let problem = thesis_sized(5);
    let solution = solve(&problem, &Settings::default()).unwrap();
    let settings = LocateSettings {
        outputs: Outputs::First(4),
        leaf_regions: 4,
        ..LocateSettings::default()
    };
    let c = build_lists(&problem, &solution, &settings, &mut |_| {}).unwrap();
    let v = c.tables.to_json();
    let text = serde_json::to_string(&v).unwrap();
    let back = crate::locate::ListTables::from_json(&serde_json::from_str(&text).unwrap()).unwrap();
    assert_eq!(back, c.tables);
    assert!(c.stats.nodes > 0, "{:?}", c.stats);
    // Corruptions each name their key.
    let corrupt = |key: &str, value: serde_json::Value| {
        let mut v = v.clone();
        v[key] = value;
        crate::locate::ListTables::from_json(&v)
            .unwrap_err()
            .to_string()
    };
    assert!(corrupt("nodes", serde_json::json!([[0, 0, 0]])).contains("lists.nodes"));
    let mut facets = c.tables.facets.clone();
    facets[0] = 1_000_000;
    assert!(corrupt("facets", serde_json::json!(facets)).contains("lists.facets"));
    assert!(corrupt("region_start", serde_json::json!([0])).contains("lists.region_start"));
    assert!(corrupt("entries", serde_json::json!([-1])).contains("lists.entries"));
    assert!(corrupt("rows", serde_json::json!([[1.0]])).contains("lists.rows"));
    assert!(corrupt("n_params", serde_json::json!(0)).contains("lists.n_params"));
}
