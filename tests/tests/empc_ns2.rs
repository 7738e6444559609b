//! kestrel-empc on the thesis problem with `N_s = 2` (N = 2, blocks [1, 1],
//! 8 variables) of the identified black-box model: the problem kestrel-mpc
//! builds has the shape of the checked-in fixture
//! `crates/empc/tests/data/thesis-ns2.json` (kestrel-empc's `tests/ns2.rs`
//! checks its search trees on a sub-box in CI; the whole box needs more
//! than the 32767 nodes of the `u16` child codes and builds in the wide
//! `u32` layout in minutes: its `whole_box` example and ignored test), and
//! `EMPC_DUMP=dir` writes it again (for a re-identified model).

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
        blocking: Some(Blocking::thesis(2, 2).unwrap()),
        ..ProblemSize::Thesis.settings(q1, q2)
    };
    let trim = tricopter_trim(&model).unwrap();
    MpcProblem::build(&model, &trim.bounds(), &settings)
        .unwrap()
        .to_mpqp()
}

#[test]
fn ns2_problem_has_the_fixture_shape() {
    let prob = ns2_problem();
    if let Ok(dir) = std::env::var("EMPC_DUMP") {
        std::fs::write(format!("{dir}/thesis-ns2.json"), prob.to_json_string()).unwrap();
    }
    let fixture =
        MpqpProblem::from_json_str(include_str!("../../crates/empc/tests/data/thesis-ns2.json"))
            .unwrap();
    assert_eq!((prob.p(), prob.n(), prob.m()), (9, 8, 16));
    assert_eq!(
        (fixture.p(), fixture.n(), fixture.m()),
        (prob.p(), prob.n(), prob.m())
    );
    // The same constraint rows (input bounds of both moves); the weights
    // and bounds follow the model fixture, which may be re-identified.
    assert_eq!(fixture.g, prob.g);
    if fixture.h != prob.h || fixture.w != prob.w {
        eprintln!(
            "note: models/tricopter-blackbox-5.json changed since the Ns = 2 fixture was written; regenerate it with EMPC_DUMP=dir"
        );
    }
}
