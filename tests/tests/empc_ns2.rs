//! kestrel-empc on the thesis problem with `N_s = 2` (N = 2, blocks [1, 1],
//! 8 variables) of the identified black-box model: the problem kestrel-mpc
//! builds has the shape of the checked-in fixture
//! `crates/empc/tests/data/thesis-ns2.json` (kestrel-empc's `tests/ns2.rs`
//! checks its search trees on a sub-box in CI; the whole box needs more
//! than the 32767 nodes of the `u16` child codes and builds in the wide
//! `u32` layout in minutes: its `whole_box` example and ignored test). The
//! fixture is written by `kestrel codegen` (kestrel-tricopter's
//! `firmware::ns2_problem` of `models/tricopter-blackbox-5.json`); this test
//! fails when it is stale.

use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_mpc::{Blocking, MpcProblem, MpcSettings};
use kestrel_tricopter::{ProblemSize, default_weights, tricopter_trim};

fn blackbox_model() -> SsModel {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../models/tricopter-blackbox-5.json"
    );
    SsModel::read(std::path::Path::new(path)).unwrap()
}

/// The Ns = 2 thesis problem (as kestrel-tricopter's `firmware::ns2_problem`).
fn ns2_problem() -> MpqpProblem {
    let model = blackbox_model();
    let (q1, q2) = default_weights();
    let settings = MpcSettings {
        blocking: Some(Blocking::control_horizon(2, 2).unwrap()),
        ..ProblemSize::Thesis.settings(q1, q2)
    };
    let trim = tricopter_trim(&model).unwrap();
    MpcProblem::build(&model, &trim.constrain(settings))
        .unwrap()
        .to_mpqp()
}

#[test]
fn ns2_problem_has_the_fixture_shape() {
    let prob = ns2_problem();
    let text = include_str!("../../crates/empc/tests/data/thesis-ns2.json");
    let fixture = MpqpProblem::from_json_str(text).unwrap();
    assert_eq!((prob.p(), prob.n(), prob.m()), (9, 8, 16));
    assert_eq!(
        (fixture.p(), fixture.n(), fixture.m()),
        (prob.p(), prob.n(), prob.m())
    );
    // The same constraint rows (input bounds of both moves).
    assert_eq!(fixture.g, prob.g);
    // The weights and bounds follow the design model, which may be
    // re-identified: the fixture is this very problem.
    assert_eq!(
        text,
        prob.to_json_string(),
        "crates/empc/tests/data/thesis-ns2.json is stale: run `kestrel codegen`"
    );
}
