//! [`FlashLists`] against the slices it was written from.

use super::*;
use kestrel_empc::locate::{LocateSettings, build_lists};
use kestrel_empc::testing::thesis_sized;
use kestrel_empc::{Outputs, Settings, evaluate_lists, solve};

/// A small xorshift for parameters (no rand dependency here).
fn uniform(seed: &mut u64) -> f32 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 40) as f32 / (1u64 << 24) as f32
}

#[test]
fn flash_lists_evaluate_as_the_slices_bit_for_bit() {
    let problem = thesis_sized(3);
    let solution = solve(&problem, &Settings::default()).unwrap();
    let settings = LocateSettings {
        outputs: Outputs::First(4),
        leaf_regions: 3,
        ..LocateSettings::default()
    };
    let c = build_lists(&problem, &solution, &settings, &mut |_| {}).unwrap();
    let single = c.tables.narrow().unwrap().cast::<f32>();
    let t = single.tables();
    let (bytes, layout) = list_bytes(&t);
    assert_eq!(layout.bytes(), Some(bytes.len() as u32));
    let flash = FlashLists::<_, f32>::new(&bytes[..], layout).unwrap();
    let p = t.n_params;
    let mut seed = 0x2545_F491_u64;
    let (mut s1, mut s2) = (vec![0.0f32; p], vec![0.0f32; p]);
    let (mut z1, mut z2) = ([0.0f32; 4], [0.0f32; 4]);
    let mut tested = 0;
    for _ in 0..3000 {
        // Some points a little outside the box.
        let theta: Vec<f32> = (0..p)
            .map(|j| {
                let (lo, hi) = (t.theta_lb[j], t.theta_ub[j]);
                lo + (hi - lo) * (1.1 * uniform(&mut seed) - 0.05)
            })
            .collect();
        let a = evaluate_lists(&t, &theta, &mut s1, &mut z1).unwrap();
        let b = evaluate_lists(&flash, &theta, &mut s2, &mut z2).unwrap();
        assert_eq!(a, b);
        assert_eq!(z1.map(f32::to_bits), z2.map(f32::to_bits));
        tested += usize::from(a.tests > 0);
    }
    assert!(tested > 100, "{tested}");
    // Every read beyond its section is None.
    assert_eq!(flash.node(t.nodes.len()), None);
    assert_eq!(flash.leaf(t.leaves.len()), None);
    assert_eq!(flash.entry(t.entries.len()), None);
    assert_eq!(flash.region_start(t.region_start.len()), None);
    assert_eq!(flash.facet(t.facets.len()), None);
    assert_eq!(flash.hyperplane(t.hyperplanes.len()), None);
    assert_eq!(flash.theta_bounds(p), None);
    assert_eq!(flash.output_bounds(4), None);
    assert_eq!(flash.law(0, 4), None);
    assert_eq!(flash.row(0, p + 1), None);
}

#[test]
fn bad_tables_are_errors_not_panics() {
    let problem = thesis_sized(3);
    let solution = solve(&problem, &Settings::default()).unwrap();
    let settings = LocateSettings {
        outputs: Outputs::First(4),
        leaf_regions: 3,
        ..LocateSettings::default()
    };
    let c = build_lists(&problem, &solution, &settings, &mut |_| {}).unwrap();
    let single = c.tables.narrow().unwrap().cast::<f32>();
    let (bytes, layout) = list_bytes(&single.tables());
    assert!(matches!(
        FlashLists::<_, f32>::new(&bytes[..bytes.len() - 1], layout),
        Err(Error::DimensionMismatch { .. })
    ));
    // Every node's children and every leaf's range pointing far away.
    let mut bad = bytes.clone();
    let end = layout.offsets().unwrap().entries as usize;
    for w in bad[..end].chunks_mut(2) {
        w.copy_from_slice(&0x7FF0u16.to_le_bytes());
    }
    let flash = FlashLists::<_, f32>::new(&bad[..], layout).unwrap();
    let p = usize::from(layout.n_params);
    let theta: Vec<f32> = (0..p).map(|j| single.tables().theta_lb[j]).collect();
    let (mut s, mut z) = (vec![0.0f32; p], [0.0f32; 4]);
    assert_eq!(
        evaluate_lists(&flash, &theta, &mut s, &mut z),
        Err(Error::OutOfRange)
    );
}
