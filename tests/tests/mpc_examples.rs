//! kestrel-mpc's examples on plants that are not rotorcraft, run as tests:
//! each example checks its closed loop at every sample (the limits), these
//! tests check what it reports at the end.

#[path = "../../crates/mpc/examples/rate_limit.rs"]
mod rate_limit;

#[path = "../../crates/mpc/examples/cd_player.rs"]
mod cd_player;

use std::path::Path;

#[test]
fn double_integrator_keeps_its_rate_limit_and_settles() {
    let s = rate_limit::run(1.0, 200).unwrap();
    // The rate limit binds (and is kept: checked at every sample by `run`).
    assert!(
        s.max_du > 0.99 * rate_limit::DU_MAX && s.max_du <= rate_limit::DU_MAX + 1e-9,
        "{s:?}"
    );
    assert!(s.max_u <= rate_limit::U_MAX + 1e-9, "{s:?}");
    assert!(s.settled_at.is_some_and(|k| k < 150), "{s:?}");
    assert!(s.final_error < 1e-3, "{s:?}");
}

#[test]
fn cd_player_arm_keeps_its_output_limits() {
    let data =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/daisy/cd_player_arm.csv");
    let s = cd_player::run(&data, 80).unwrap();
    let (y, r) = (cd_player::Y_MAX, cd_player::REFERENCE);
    // Hard limits: never beyond them (checked at every sample by `run`);
    // the first output is held at its limit, the second reaches its
    // reference inside them.
    assert!(s.hard.max_violation <= 1e-7, "{s:?}");
    assert!((s.hard.final_output[0] - y).abs() < 1e-3, "{s:?}");
    assert!((s.hard.final_output[1] - r[1]).abs() < 0.01, "{s:?}");
    // A weak soft penalty: the first output settles between the limit and
    // the reference, beyond the limit by the slack the QP reports.
    let y1 = s.soft_weak.final_output[0];
    assert!(y1 > y + 0.05 && y1 < r[0] - 0.05, "{s:?}");
    assert!(
        s.soft_weak.max_slack >= s.soft_weak.max_violation - 1e-7,
        "{s:?}"
    );
    // The exact penalty gives the hard problem's solution where that is
    // feasible.
    assert!(s.soft_exact.max_violation < 1e-6, "{s:?}");
    for i in 0..2 {
        let d = s.soft_exact.final_output[i] - s.hard.final_output[i];
        assert!(d.abs() < 1e-6, "{s:?}");
    }
}
