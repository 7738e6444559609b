//! The exact MPC's fallback in flight: the `qp-fallback-test` build
//! (kestrel-qp's iteration cap 1, cold starts) flown against the nonlinear
//! plant with rate references that drive several inputs to their bounds
//! at once, so that many periods need two or more active-set changes and
//! answer the law's fallback (the unconstrained optimum `-H^-1 q` clamped
//! to the period's box).

use super::{CYCLES_PER_PERIOD, Solver, build_firmware, fly_references, qp_law};
use kestrel_avr_rt::frame::status;

/// Rate references switching every 0.5 s between `[3, -3, 2]` and
/// `[-3, 3, -2]` rad/s (the edges of the design's parameter box).
fn aggressive(t: f64) -> [f64; 3] {
    if ((t / 0.5) as u64).is_multiple_of(2) {
        [3.0, -3.0, 2.0]
    } else {
        [-3.0, 3.0, -2.0]
    }
}

/// Every period answered in time with pulses within the limits, the
/// fallback taken in the same periods as by the host law with the same
/// cap, and the pulses equal to the host's within 1 us.
#[test]
fn hil_qp_fallback_pwm_within_limits() {
    let elf = build_firmware(&["qp-fallback-test"], false);
    let periods = 500;
    let fl = fly_references(
        &elf,
        periods,
        Solver::Qp {
            fallback_test: true,
        },
        aggressive,
    );
    for (k, r) in fl.replies.iter().enumerate() {
        let r = r.unwrap_or_else(|| panic!("no reply in period {k}"));
        assert_eq!(
            r.status & status::OVERRUN,
            0,
            "deadline missed at period {k}"
        );
        assert!(r.period_cycles < CYCLES_PER_PERIOD as u32);
        for w in &r.pwm[..3] {
            assert!((1000..=2000).contains(w), "ESC pulse {w} at period {k}");
        }
        assert!(
            (1200..=1800).contains(&r.pwm[3]),
            "servo pulse {} at period {k}",
            r.pwm[3]
        );
    }
    let fw = fl
        .qp_iterations
        .iter()
        .filter(|(_, f)| f & qp_law::FALLBACK != 0)
        .count();
    let host = fl
        .qp_iterations
        .iter()
        .filter(|(h, _)| h & qp_law::FALLBACK != 0)
        .count();
    let differ = fl.qp_iterations.iter().filter(|(h, f)| h != f).count();
    let peak = fl
        .rates
        .iter()
        .flat_map(|w| w.iter().map(|v| v.abs()))
        .fold(0.0f64, f64::max);
    println!(
        "qp-fallback-test f32: {} solved periods, fallback in {fw} (host {host}), iterations differing {differ}; max |PWM - f64 ref| = {} us; peak body rate {peak:.2} rad/s",
        fl.qp_iterations.len(),
        fl.pwm_diff_max
    );
    assert!(fw > 0, "no period fell back");
    assert!(
        differ * 100 <= fl.qp_iterations.len(),
        "iterations differ in {differ} periods"
    );
    assert!(
        fl.pwm_diff_max <= 1,
        "PWM differs from the host's by {} us",
        fl.pwm_diff_max
    );
}
