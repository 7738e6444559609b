//! The firmware's exact MPC at pseudo-random parameters of the whole
//! parameter box (features `qp-check`: kestrel-qp in f32; `qp16-check`:
//! `kestrel_avr_rt::qp16` in fixed point; avr/firmware/src/qp_check.rs),
//! against kestrel-qp's f64 law on the host: cold starts, warm starts
//! along a random walk, and the iteration cap 1 (the fallback).

use super::{avr_size, build_firmware, generated, host_qp_law, min_mean_max, qp_law, read_frames};
use avr_tester::AvrTester;
use kestrel_avr_rt::control::LawInfo;
use kestrel_avr_rt::cycles::CycleStats;
use kestrel_avr_rt::frame::{FrameDecoder, Kind};
use kestrel_core::ControlLaw;
use std::collections::BTreeMap;

/// Solves per part (`CHECK_SAMPLES` in avr/firmware/src/qp_check.rs).
const PART: usize = 150;

/// One solve on the target.
#[derive(Clone, Copy, Debug)]
pub(super) struct Sample {
    pub(super) theta: [f32; generated::NP],
    pub(super) iterations: u16,
    pub(super) cycles: u32,
    pub(super) u: [f32; 4],
}

/// The result frame's payload (24 bytes) with its parameter.
pub(super) fn parse_result(p: &[u8], theta: [f32; generated::NP]) -> Sample {
    let f32_at = |i: usize| f32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]]);
    Sample {
        theta,
        iterations: u16::from_le_bytes([p[2], p[3]]),
        cycles: u32::from_le_bytes([p[4], p[5], p[6], p[7]]),
        u: std::array::from_fn(|k| f32_at(8 + 4 * k)),
    }
}

/// Runs the check firmware built with `features` and collects its
/// `3 PART` solves.
fn on_target(features: &[&str]) -> (Vec<Sample>, (u64, u64), AvrTester, FrameDecoder) {
    let elf = build_firmware(features, false);
    let mut avr = AvrTester::atmega2560().with_clock_of_16_mhz().load(&elf);
    let mut dec = FrameDecoder::new();
    let mut theta: Option<(u16, [f32; generated::NP])> = None;
    let mut got = Vec::new();
    for _ in 0..5000 {
        avr.run_for_ms(2);
        for f in read_frames(&mut avr, &mut dec) {
            let p = f.payload();
            if f.kind != Kind::Bench {
                continue;
            }
            let f32_at = |i: usize| f32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]]);
            let index = u16::from_le_bytes([p[0], p[1]]);
            match p.len() {
                38 => theta = Some((index, std::array::from_fn(|j| f32_at(2 + 4 * j)))),
                24 => {
                    let (i, th) = theta.take().expect("parameter frame before its result");
                    assert_eq!((i, usize::from(i)), (index, got.len()), "frames in order");
                    got.push(parse_result(p, th));
                }
                n => panic!("unexpected Bench frame of {n} bytes"),
            }
        }
        if got.len() == 3 * PART {
            return (got, avr_size(&elf), avr, dec);
        }
    }
    panic!("only {} of {} qp-check samples", got.len(), 3 * PART);
}

/// The f32 build (kestrel-qp in f32): outputs within 0.05 us of the f64
/// law's.
#[test]
fn qp_f32_on_target_equals_host() {
    check_on_target(&["qp-check"], "f32", "qp", 0.05);
}

/// The fixed-point build (`kestrel_avr_rt::qp16`'s per-set kernel,
/// `fixed-mac`): outputs within 0.05 us of the f64 law's.
#[test]
fn qp16_fixed_on_target_equals_host() {
    check_on_target(&["qp16-check", "fixed-mac"], "fixed-mac", "qp16", 0.05);
}

/// The fixed-point build with the LDL'-update kernel (`qp16-ldl`).
#[test]
fn qp16_ldl_fixed_on_target_equals_host() {
    check_on_target(
        &["qp16-check", "qp16-ldl", "fixed-mac"],
        "fixed-mac",
        "qp16-ldl",
        0.05,
    );
}

/// The firmware's solves equal the host's f64 law at the same parameters:
/// outputs within `tol` us, the same iterations (active-set changes) in
/// all but 1 % of the solves, the fallback in as many capped solves (to
/// 1 %), the fallback's outputs within the period's box. Prints the
/// cycles per part and per iteration count (`QP-CHECK {json}` lines with
/// `KESTREL_HIL_REPORT=1`).
fn check_on_target(features: &[&str], scalar: &str, solver: &str, tol: f64) {
    let (samples, (flash, ram), mut avr, mut dec) = on_target(features);
    let nx = generated::NX;
    // The build's host reference: warm starts along the walk (qp), or cold
    // every period (qp16, qp16-ldl: the law never warm-starts).
    let (cap, warm_law) = super::qp_reference(solver);
    let mut cold = host_qp_law(cap, warm_law);
    let mut capped = host_qp_law(1, false);
    let box_of = super::host_qp_box;
    // Largest output difference where the iterations agree, and where
    // they do not (a bound at the edge of the primal tolerance in one
    // arithmetic and not in the other: another active set, another point).
    let mut worst = 0.0f64;
    let mut worst_differing = 0.0f64;
    let mut differ = [0usize; 3];
    let mut fallbacks = [(0usize, 0usize); 3];
    let mut stats = [CycleStats::new(), CycleStats::new(), CycleStats::new()];
    let mut by_iterations: BTreeMap<(usize, u16), CycleStats> = BTreeMap::new();
    for (i, s) in samples.iter().enumerate() {
        let part = i / PART;
        let law = if part == 2 { &mut capped } else { &mut cold };
        if part == 0 || i == PART {
            law.restart();
        }
        let th: Vec<f64> = s.theta.iter().map(|&v| f64::from(v)).collect();
        let mut u = [0.0; 4];
        law.control(&th[..nx], &th[nx..], &mut u)
            .unwrap_or_else(|e| panic!("host law at sample {i}: {e:?}"));
        assert_ne!(s.iterations, 0xFFFF, "firmware law error at sample {i}");
        let host_it = law.iterations();
        differ[part] += usize::from(host_it != s.iterations);
        let fb = |it: u16| usize::from(it & qp_law::FALLBACK != 0);
        fallbacks[part].0 += fb(s.iterations);
        fallbacks[part].1 += fb(host_it);
        for (a, b) in s.u.iter().zip(&u) {
            let e = (f64::from(*a) - b).abs();
            if host_it == s.iterations {
                worst = worst.max(e);
            } else {
                worst_differing = worst_differing.max(e);
            }
        }
        if s.iterations & qp_law::FALLBACK != 0 {
            let (lb, ub) = box_of(&th);
            for k in 0..4 {
                let v = f64::from(s.u[k]);
                assert!(
                    v >= lb[k] - 1e-3 && v <= ub[k] + 1e-3,
                    "fallback output {k} = {v} outside [{}, {}] at sample {i}",
                    lb[k],
                    ub[k]
                );
            }
        }
        stats[part].add(s.cycles);
        by_iterations
            .entry((part, s.iterations))
            .or_default()
            .add(s.cycles);
    }
    // The walk's part is labelled by how the law starts there: `warm` for
    // `qp`, `walk-cold` for the qp16 builds (cold every period).
    let names = ["cold", if warm_law { "warm" } else { "walk-cold" }, "cap1"];
    for (p, name) in names.iter().enumerate() {
        println!(
            "{solver} {scalar} on target, {name}: whole law {} cycles; iterations differing from the host's {}; fallbacks firmware {} host {}",
            min_mean_max(&stats[p]),
            differ[p],
            fallbacks[p].0,
            fallbacks[p].1
        );
    }
    for ((p, it), st) in &by_iterations {
        println!(
            "{solver} {scalar} on target, {} with {} iterations{}: {} solves, {} cycles",
            names[*p],
            it & !qp_law::FALLBACK,
            if it & qp_law::FALLBACK != 0 {
                " (fallback)"
            } else {
                ""
            },
            st.count,
            min_mean_max(st)
        );
    }
    println!(
        "{solver} {scalar} on target: largest |u - host f64| = {worst:.2e} us (where the iterations differ: {worst_differing:.2e} us); flash {flash} B, RAM {ram} B"
    );
    if std::env::var_os("KESTREL_HIL_REPORT").is_some() {
        for (p, name) in names.iter().enumerate() {
            let s = &stats[p];
            println!(
                "QP-CHECK {{\"scalar\": \"{scalar}\", \"solver\": \"{solver}\", \"start\": \"{name}\", \"samples\": {}, \"cycles\": {{\"min\": {}, \"mean\": {:.1}, \"max\": {}}}, \"max_iterations\": {}}}",
                s.count,
                s.min,
                s.mean().unwrap_or(0.0),
                s.max,
                samples[p * PART..(p + 1) * PART]
                    .iter()
                    .map(|s| s.iterations & !qp_law::FALLBACK)
                    .max()
                    .unwrap_or(0)
            );
        }
    }
    super::qp_certified::check_certified(&mut avr, &mut dec, scalar, solver, tol);
    assert!(worst <= tol, "outputs differ from the host's by {worst} us");
    for p in 0..3 {
        assert!(
            differ[p] * 100 <= PART,
            "{}: iterations differ in {} solves",
            names[p],
            differ[p]
        );
    }
    assert_eq!(fallbacks[0], (0, 0), "fallback with the normal cap (cold)");
    assert_eq!(fallbacks[1], (0, 0), "fallback with the normal cap (warm)");
    assert!(fallbacks[2].0 > 0, "the capped law never fell back");
    assert!(
        fallbacks[2].0.abs_diff(fallbacks[2].1) * 100 <= PART,
        "fallbacks differ: firmware {}, host {}",
        fallbacks[2].0,
        fallbacks[2].1
    );
}
