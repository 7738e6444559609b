//! kestrel-fgm's kernel timed on the AVR at boot (the `fgm-bench`
//! firmware), beside the closed-loop HIL runs.

use super::{avr_size, build_firmware, read_frames};
use avr_tester::AvrTester;
use kestrel_avr_rt::frame::{Bench, FrameDecoder};

/// kestrel-fgm's run-time solver on the AVR: the `fgm-bench` firmware times
/// cold solves of a thesis-sized problem (4 variables, 9 parameters) with
/// 1, 12, 56 and 91 iterations at boot (the thesis's Table 7.2 counts).
fn fgm_bench(scalar_features: &[&str], scalar: &str) {
    let mut features = scalar_features.to_vec();
    features.push("fgm-bench");
    let elf = build_firmware(&features, false);
    let mut avr = AvrTester::atmega2560().with_clock_of_16_mhz().load(&elf);
    let mut dec = FrameDecoder::new();
    let mut benches = vec![];
    for _ in 0..400 {
        avr.run_for_ms(1);
        benches.extend(
            read_frames(&mut avr, &mut dec)
                .iter()
                .filter_map(|f| Bench::from_frame(f).ok()),
        );
        if benches.len() == 10 {
            break;
        }
    }
    assert_eq!(benches.len(), 10, "{scalar}: bench frames");
    // First the Kalman-sized step (id 100), then the fast-gradient solves.
    let kalman = benches.remove(0);
    assert_eq!((kalman.id, kalman.n, kalman.p), (100, 5, 3));
    let narrow = benches.remove(0);
    assert_eq!((narrow.id, narrow.n, narrow.p), (101, 5, 3));
    for (b, what) in benches.drain(..4).zip([
        "round_shift",
        "mul_q15",
        "Row16::dot (4 terms)",
        "Row16::apply (4 terms)",
    ]) {
        println!(
            "{scalar} micro: {what}: {:.0} cycles per call (64 calls, loop included)",
            b.cycles as f64 / 64.0
        );
    }
    println!(
        "kalman-sized step, Q16 states x 16-bit coefficients (narrow MAC): {} cycles ({:.3} ms)",
        narrow.cycles,
        narrow.cycles as f64 / 16_000.0
    );
    println!(
        "{scalar} kalman-sized step (core kernels, 5 states, 4 inputs, 3 outputs): {} cycles ({:.3} ms)",
        kalman.cycles,
        kalman.cycles as f64 / 16_000.0
    );
    for b in &benches {
        assert_eq!(b.ok, 1, "{scalar}: fgm solve failed");
        assert_eq!((b.n, b.p), (4, 9));
    }
    // Fixed work per iteration: the cycles grow linearly with the count.
    let per_iter = (benches[3].cycles - benches[0].cycles) as f64 / 90.0;
    let predicted_56 = benches[0].cycles as f64 + 55.0 * per_iter;
    assert!((benches[2].cycles as f64 - predicted_56).abs() < 0.05 * predicted_56);
    let (flash, ram) = avr_size(&elf);
    let at56 = benches[2].cycles;
    println!(
        "{scalar} fgm: {} cycles per iteration; 1/12/56/91 iterations: {}/{}/{}/{} cycles ({:.2} ms at 56); flash {flash} B, RAM {ram} B",
        per_iter.round(),
        benches[0].cycles,
        benches[1].cycles,
        at56,
        benches[3].cycles,
        at56 as f64 / 16_000.0
    );
    if std::env::var_os("KESTREL_HIL_REPORT").is_some() {
        println!(
            "HIL-BENCH {{\"scalar\": \"{scalar}\", \"solver\": \"fgm-kernel\", \"kalman_cycles\": {{\"min\": {kc}, \"mean\": {kc}, \"max\": {kc}}}, \"solver_cycles\": {{\"min\": {at56}, \"mean\": {at56}, \"max\": {at56}}}, \"period_cycles\": null, \"iterations\": 56, \"flash_bytes\": {flash}, \"ram_bytes\": {ram}, \"cycles_per_iteration\": {:.0}, \"note\": \"kestrel-fgm kernel timed at boot on synthetic thesis-sized tables (n=4, p=9); a kernel benchmark, the closed-loop figures are the HIL-REPORT lines; 56 = the thesis's accurate count; kalman_cycles = one 5-state Kalman-shaped step with kestrel-core kernels; the same step with 16-bit coefficients and the narrow MAC: {nk} cycles\"}}",
            per_iter,
            kc = kalman.cycles,
            nk = narrow.cycles
        );
    }
}

#[test]
fn fgm_kernel_cycles_f32() {
    fgm_bench(&[], "f32");
}

#[test]
fn fgm_kernel_cycles_fixed_q16() {
    fgm_bench(&["fixed"], "fixed");
}

#[test]
fn fgm_kernel_cycles_fixed_q16_mac() {
    fgm_bench(&["fixed-mac"], "fixed-mac");
}
