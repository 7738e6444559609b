//! The firmware's explicit MPC on the target against the host walk of the
//! same 16-bit table, bit for bit (thesis-sized, f32 and Ns = 2 builds).

use super::{
    avr_size, build_firmware, empc, generated, min_mean_max, ns2_empc, ns2_tables, read_frames,
    repo_root,
};
use avr_tester::AvrTester;
use kestrel_avr_rt::cycles::CycleStats;
use kestrel_avr_rt::frame::{FrameDecoder, Kind};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// One parameter of the firmware's on-target explicit-MPC check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct EmpcSample {
    law: u16,
    steps: u16,
    cycles: u32,
    z: [i32; 4],
    /// Cycles of the whole law (`control`: quantisation, walk, outputs).
    control_cycles: u32,
    /// Nodes visited by `control`.
    control_steps: u16,
    /// Wrapping sum of `control`'s outputs' Q15.16 bits.
    control_sum: u32,
}

/// The `empc-check` firmware evaluates the 16-bit tree (the assembly walk
/// from flash) at `EMPC_CHECK_SAMPLES` pseudo-random parameters at boot;
/// the host walks the same table in Rust at the same parameters (the
/// same generator, `Empc16Law::box_sample`): law, nodes visited and the
/// four outputs must agree bit for bit. Returns the on-target samples.
fn empc_on_target<T: kestrel_avr_rt::progmem::TableRead + Copy, const ROWS: usize>(
    features: &[&str],
    table: T,
    layout: kestrel_avr_rt::explicit::tree16::Tree16Layout,
    n: usize,
) -> Vec<EmpcSample> {
    use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
    let elf = build_firmware(features, false);
    let mut avr = AvrTester::atmega2560().with_clock_of_16_mhz().load(&elf);
    let mut dec = FrameDecoder::new();
    let mut got: Vec<EmpcSample> = Vec::new();
    for _ in 0..5000 {
        avr.run_for_ms(2);
        for f in read_frames(&mut avr, &mut dec) {
            let p = f.payload();
            if f.kind == Kind::Bench && p.len() == 36 {
                let u16_at = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
                let u32_at = |i: usize| u32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]]);
                assert_eq!(u16_at(0) as usize, got.len(), "sample frames in order");
                got.push(EmpcSample {
                    law: u16_at(2),
                    steps: u16_at(4),
                    cycles: u32_at(6),
                    z: std::array::from_fn(|k| u32_at(10 + 4 * k) as i32),
                    control_cycles: u32_at(26),
                    control_steps: u16_at(30),
                    control_sum: u32_at(32),
                });
            }
        }
        if got.len() >= n {
            break;
        }
    }
    assert_eq!(got.len(), n, "on-target explicit MPC samples");
    let tree = Tree16::new(table, layout).unwrap();
    let mut host =
        Empc16Law::<f64, _, { generated::NP }, 4, ROWS>::new(tree, generated::NX).unwrap();
    let mut whole =
        Empc16Law::<f64, _, { generated::NP }, 4, ROWS>::new(tree, generated::NX).unwrap();
    // The f32 builds' whole law takes f32 parameters (`check_f32`): the
    // host's f32 law (Rust: to_q16, quantisation, walk, outputs).
    let f32_build = !features.iter().any(|f| f.starts_with("fixed"));
    let mut whole32 =
        Empc16Law::<f32, _, { generated::NP }, 4, ROWS>::new(tree, generated::NX).unwrap();
    let mut non_finite = 0;
    use kestrel_core::ControlLaw as _;
    let mut seed = 0x2545_f491u32;
    let mut moved = 0;
    for (i, g) in got.iter().enumerate() {
        let q = host.box_sample(&mut seed);
        let r = host.evaluate_raw(&q).unwrap();
        assert_eq!(
            (g.law, g.steps, g.z),
            (r.law, r.steps, r.z),
            "sample {i}: firmware (law, nodes, outputs) differ from the host walk at {q:?}"
        );
        // The whole law near the same parameter (`check_bits`: on the grid,
        // off it, or beyond the box): the host's whole law (Rust
        // quantisation, walk, outputs rounded to Q15.16) at the same bits.
        let bits = host.check_bits(&q, i as u16);
        let (steps, sum) = if f32_build {
            use kestrel_avr_rt::output::RtScalar as _;
            let theta = whole32.check_f32(&bits, i as u16);
            let mut u = [0.0f32; 4];
            let r = whole32.control(&theta[..generated::NX], &theta[generated::NX..], &mut u);
            if r.is_err() {
                assert!(theta.iter().any(|t| !t.is_finite()), "{r:?} at {theta:?}");
                non_finite += 1;
            }
            let sum = u
                .iter()
                .fold(0u32, |a, v| a.wrapping_add(v.to_q16().unwrap() as u32));
            (kestrel_avr_rt::control::LawInfo::iterations(&whole32), sum)
        } else {
            let theta: Vec<f64> = bits.iter().map(|&b| f64::from(b) / 65536.0).collect();
            let mut u = [0.0f64; 4];
            whole
                .control(&theta[..generated::NX], &theta[generated::NX..], &mut u)
                .unwrap();
            let sum = u
                .iter()
                .fold(0u32, |a, &v| a.wrapping_add((v * 65536.0) as i32 as u32));
            (kestrel_avr_rt::control::LawInfo::iterations(&whole), sum)
        };
        assert_eq!(
            (g.control_steps, g.control_sum),
            (steps, sum),
            "sample {i}: the firmware's whole law differs from the host's at {bits:?}"
        );
        // (Not vacuous: the moved parameters change the outputs.)
        let k = i32::from(layout.scale) - 16;
        let on_grid = r.z.iter().fold(0u32, |a, &z| {
            let q16 = if k > 0 {
                ((i64::from(z) + (1 << (k - 1))) >> k) as i32
            } else {
                z << -k
            };
            a.wrapping_add(q16 as u32)
        });
        moved += usize::from(sum != on_grid);
    }
    assert!(
        moved >= n / 4,
        "only {moved} of {n} parameters off the grid or the box changed the law's outputs"
    );
    if f32_build {
        assert!(whole32.outside() > 0, "no parameter beyond the box");
        assert!(non_finite > 0, "no non-finite parameter");
    } else {
        assert!(whole.outside() > 0, "no parameter beyond the box");
    }
    got
}

/// The firmware's explicit MPC (N = 2, Ns = 1) equals the host walk on 200
/// parameters; prints the walk's cycles (quantised parameter to outputs).
#[test]
fn empc_on_target_equals_host_walk() {
    // The design's table (what the build writes into generated_empc.rs).
    let q = kestrel_avr_rt::explicit::quantize::quantize_tree(&empc().tables).unwrap();
    let got = empc_on_target::<_, 256>(&["empc-check", "fixed-mac"], &q.bytes[..], q.layout, 200);
    let (mut s, mut c) = (CycleStats::new(), CycleStats::new());
    for g in &got {
        s.add(g.cycles);
        c.add(g.control_cycles);
    }
    let nodes = got.iter().map(|g| g.steps as f64).sum::<f64>() / got.len() as f64;
    println!(
        "empc on target (N = 2, Ns = 1, 200 random parameters): walk {} cycles, whole law {} cycles, {nodes:.1} nodes",
        min_mean_max(&s),
        min_mean_max(&c),
    );
}

/// The f32 firmware's explicit MPC (the routine converting the f32
/// parameters itself) equals the host's f32 law bit for bit on 200
/// parameters, some with bits below Q15.16's resolution, beyond the box or
/// non-finite (`Empc16Law::check_f32`); prints its cycles.
#[test]
fn empc_f32_on_target_equals_host() {
    let q = kestrel_avr_rt::explicit::quantize::quantize_tree(&empc().tables).unwrap();
    let got = empc_on_target::<_, 256>(&["empc-check"], &q.bytes[..], q.layout, 200);
    let (mut s, mut c) = (CycleStats::new(), CycleStats::new());
    for g in &got {
        s.add(g.cycles);
        c.add(g.control_cycles);
    }
    println!(
        "empc on target, f32 (200 parameters): walk {} cycles, whole law {} cycles",
        min_mean_max(&s),
        min_mean_max(&c),
    );
}

/// The firmware's Ns = 2 explicit MPC (`empc-ns2`: the wide 16-bit table
/// of [`ns2_empc`] in flash chunks, the Rust walk with a 64-row
/// direct-mapped cache) agrees with the f64 tree and equals the host walk
/// of the same table on 200 parameters; prints its cycles and the
/// firmware's flash and RAM.
#[test]
fn empc_ns2_on_target_equals_host_walk() {
    let features = ["empc-ns2", "empc-check", "fixed-mac"];
    let q = ns2_tables();
    // The 16-bit table against the f64 tree at 2000 random parameters of
    // its box: the same law up to the rounding margin of a hyperplane, and
    // within the proved output bound where the law is the same.
    let t = &ns2_empc().tables;
    let mut rng = SplitMix64::seed_from_u64(0x2545_F491_4F6C_DD1D);
    let thetas: Vec<[f64; 9]> = (0..2000)
        .map(|_| {
            std::array::from_fn(|j| {
                let u = rng.random::<f64>();
                t.theta_lb[j] + u * (t.theta_ub[j] - t.theta_lb[j])
            })
        })
        .collect();
    let check = kestrel_avr_rt::explicit::quantize::check_tree16::<9, 4>(&q, t, &thetas).unwrap();
    println!(
        "empc-ns2 design: {} laws, depth {}, {} nodes; 16-bit table {} bytes; {check:?}",
        ns2_empc().stats.distinct_laws,
        ns2_empc().stats.depth,
        ns2_empc().stats.nodes,
        q.bytes.len()
    );
    assert!(check.max_output_error_same_law <= q.output_error_bound);
    assert!(q.output_error_bound < 1.0, "{} us", q.output_error_bound);
    // Every ill-conditioned hyperplane has a row of its own (0 when written).
    assert!(check.law_mismatches <= 10, "{check:?}");
    let got = empc_on_target::<_, 64>(&features, &q.bytes[..], q.layout, 200);
    let (mut s, mut c) = (CycleStats::new(), CycleStats::new());
    for g in &got {
        s.add(g.cycles);
        c.add(g.control_cycles);
    }
    let nodes = got.iter().map(|g| g.steps as f64).sum::<f64>() / got.len() as f64;
    let (flash, ram) = avr_size(
        &repo_root()
            .join("avr/target/hil")
            .join(format!("{}.elf", features.join("-"))),
    );
    println!(
        "empc-ns2 on target ({} bytes of table, 200 random parameters): walk {} cycles, whole law {} cycles, {nodes:.1} nodes; firmware flash {flash} B, RAM {ram} B",
        q.bytes.len(),
        min_mean_max(&s),
        min_mean_max(&c),
    );
}
