//! The firmware's 16-bit explicit MPC (`explicit::tree16`) on the
//! thesis-sized problem of the identified model, against kestrel-empc's f64
//! tree and against the exact region laws: the same law at every region's
//! Chebyshev centre and at 10^4 random parameters (but for parameters
//! within the rounding margin of a tree hyperplane), the output error
//! within the design's proved bound where the law agrees, no overflow of
//! the 32-bit sum at any corner of the box, and the table under 8 kB.

use kestrel_avr_rt::explicit::quantize::{check_tree16, quantize_tree};
use kestrel_avr_rt::explicit::tree16::Tree16Layout;
use kestrel_core::formats::SsModel;
use kestrel_empc::{
    ExplicitController, MpqpSolution, Outputs, Settings, TreeSettings, build_controller,
};
use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

const P: usize = 9;
const NU: usize = 4;

/// The explicit controller of the firmware design and its mpQP solution,
/// solved once per test binary.
fn controller() -> &'static (ExplicitController, MpqpSolution) {
    static C: std::sync::OnceLock<(ExplicitController, MpqpSolution)> = std::sync::OnceLock::new();
    C.get_or_init(|| {
        let model = SsModel::from_json_str(kestrel_tricopter::IDENTIFIED_MODEL_JSON).unwrap();
        let d = FirmwareDesign::from_model(&model, &DesignSettings::default()).unwrap();
        let solution = kestrel_empc::solve(&d.problem, &Settings::default()).unwrap();
        let tree = TreeSettings {
            outputs: Outputs::First(NU),
            ..Default::default()
        };
        (
            build_controller(&d.problem, &solution, &tree).unwrap(),
            solution,
        )
    })
}

fn uniform(lb: &[f64], ub: &[f64], n: usize) -> Vec<[f64; P]> {
    // The workspace's seeded generator.
    let mut rng = SplitMix64::seed_from_u64(0x9E37_79B9_7F4A_7C15);
    let mut rnd = move || rng.random::<f64>();
    (0..n)
        .map(|_| std::array::from_fn(|j| lb[j] + rnd() * (ub[j] - lb[j])))
        .collect()
}

/// Row `r`'s value from the table bytes in exact (i64) arithmetic.
fn row_i64(bytes: &[u8], l: &Tree16Layout, r: usize, q: &[i64]) -> i64 {
    let at = l.rows_at() + r * l.row_bytes();
    let start = bytes[at] as usize;
    let mut acc = i32::from_le_bytes(bytes[at + 1..at + 5].try_into().unwrap()) as i64;
    for (k, qj) in q.iter().skip(start).enumerate() {
        let c = i16::from_le_bytes([bytes[at + 5 + 2 * k], bytes[at + 6 + 2 * k]]);
        acc += c as i64 * qj;
    }
    acc
}

#[test]
fn tree16_matches_the_f64_tree_on_the_thesis_problem() {
    let (c, solution) = controller();
    let q = quantize_tree(&c.tables).unwrap();
    let t = &c.tables;
    println!(
        "tree16: {} nodes, {} laws, {} rows, depth {}, scale 2^-{}, {} bytes (f32 default layout {}); row error bound {:.3} us",
        q.layout.n_nodes,
        q.layout.n_laws,
        q.layout.n_rows,
        q.depth,
        q.layout.scale,
        q.bytes.len(),
        t.bytes(4),
        q.output_error_bound
    );
    assert!(
        q.bytes.len() < kestrel_avr_rt::explicit::quantize::TABLE_BUDGET,
        "16-bit table {} bytes (target 8 kB)",
        q.bytes.len()
    );
    assert_eq!(q.depth, c.stats.depth);

    // Every region's Chebyshev centre reaches its own law.
    let centres: Vec<[f64; P]> = solution
        .regions
        .iter()
        .map(|r| std::array::from_fn(|j| r.center[j]))
        .collect();
    let at_centres = check_tree16::<P, NU>(&q, t, &centres).unwrap();
    println!("centres: {at_centres:?}");
    assert_eq!(at_centres.law_mismatches, 0);
    assert!(at_centres.max_output_error <= q.output_error_bound);

    // 10^4 random parameters in the box.
    let random = check_tree16::<P, NU>(&q, t, &uniform(&t.theta_lb, &t.theta_ub, 10_000)).unwrap();
    println!("random: {random:?}");
    // Where the law agrees the error is within the proved bound.
    assert!(random.max_output_error_same_law <= q.output_error_bound);
    assert!(
        q.output_error_bound < 1.0,
        "bound {} us",
        q.output_error_bound
    );
    // A different law only within the rounding margin of a hyperplane,
    // where the continuous law keeps the output close.
    assert!(
        random.law_mismatches <= 50,
        "{} of 10^4 parameters reach another law",
        random.law_mismatches
    );
    assert!(
        random.max_output_error < 5.0,
        "{} us",
        random.max_output_error
    );
    assert!(random.max_steps as usize <= c.stats.depth);
}

#[test]
fn tree16_sums_cannot_overflow_on_the_box() {
    let (c, _) = controller();
    let q = quantize_tree(&c.tables).unwrap();
    let l = q.layout;
    // Every corner of the quantised box (2^9), every row: the exact sum fits i32.
    let corner = |mask: usize| -> Vec<i64> {
        (0..P)
            .map(|j| {
                let b = &q.bytes[5 * j..5 * j + 5];
                let (lb, ub) = (
                    i16::from_le_bytes([b[1], b[2]]),
                    i16::from_le_bytes([b[3], b[4]]),
                );
                i64::from(if mask >> j & 1 == 1 { ub } else { lb })
            })
            .collect()
    };
    let mut largest = 0i64;
    for mask in 0..1usize << P {
        let th = corner(mask);
        for r in 0..l.n_rows {
            let v = row_i64(&q.bytes, &l, r, &th);
            largest = largest.max(v.abs());
            assert!(
                i32::try_from(v).is_ok(),
                "row {r} overflows at corner {mask:b}"
            );
        }
    }
    println!(
        "largest |row sum| on the box corners: {largest} ({:.1} % of i32)",
        100.0 * largest as f64 / i32::MAX as f64
    );
}

#[test]
fn quantize_refuses_what_it_cannot_represent() {
    let (c, _) = controller();
    let mut t = c.tables.clone();
    t.hull = vec![0.0; P + 1];
    assert!(quantize_tree(&t).is_err());
    let mut t = c.tables.clone();
    t.rows[3] = f64::NAN;
    assert!(quantize_tree(&t).is_err());
    let mut t = c.tables.clone();
    t.theta_ub[0] = f64::INFINITY;
    assert!(quantize_tree(&t).is_err());
    let mut t = c.tables.clone();
    t.rows.pop();
    assert!(quantize_tree(&t).is_err());
    let mut t = c.tables.clone();
    t.nodes[0][2] = 9999; // a child past the node table
    assert!(quantize_tree(&t).is_err());
    // Rows whose values cannot fit a 32-bit sum with 16-bit gains.
    let mut t = c.tables.clone();
    t.rows[0] = 1e12;
    assert!(quantize_tree(&t).is_err());
}

#[test]
fn wide_layout_walks_like_the_narrow_one() {
    use kestrel_avr_rt::explicit::quantize::quantize_tree_layout;
    use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
    let (c, _) = controller();
    let narrow = quantize_tree(&c.tables).unwrap();
    let wide = quantize_tree_layout(&c.tables, 32, true).unwrap();
    assert!(!narrow.layout.wide && wide.layout.wide);
    assert_eq!(wide.bytes.len(), wide.layout.bytes());
    println!(
        "narrow {} bytes, wide {} bytes",
        narrow.bytes.len(),
        wide.bytes.len()
    );
    let tn = Tree16::new(&narrow.bytes[..], narrow.layout).unwrap();
    let tw = Tree16::new(&wide.bytes[..], wide.layout).unwrap();
    let mut ln = Empc16Law::<f64, _, P, NU, 256>::new(tn, 5).unwrap();
    // A small direct-mapped cache (rows share entries): the same results.
    let mut lw = Empc16Law::<f64, _, P, NU, 16>::new(tw, 5).unwrap();
    assert!(Empc16Law::<f64, _, P, NU, 24>::new(tw, 5).is_err()); // not a power of two
    let mut seed = 7u32;
    for i in 0..10_000 {
        let q = ln.box_sample(&mut seed);
        assert_eq!(
            ln.evaluate_raw(&q).unwrap(),
            lw.evaluate_raw(&q).unwrap(),
            "sample {i}"
        );
    }
}

#[test]
fn chunked_source_refuses_bad_names_and_chunks() {
    use kestrel_avr_rt::explicit::quantize::tree16_chunked_source;
    let (c, _) = controller();
    let q = quantize_tree(&c.tables).unwrap();
    assert!(tree16_chunked_source(&q, "T", 7, "").is_err());
    assert!(tree16_chunked_source(&q, "T", 15, "").is_err());
    assert!(tree16_chunked_source(&q, "lower", 12, "").is_err());
    assert!(tree16_chunked_source(&q, "9T", 12, "").is_err());
    let s = tree16_chunked_source(&q, "T", 12, "x").unwrap();
    assert!(s.contains(&format!("pub static T_1: [u8; {}]", q.bytes.len() - 4096)));
    assert!(s.contains("pub static T_0: [u8; 4096]"));
}
