//! The tricopter's signal names, and the note the tricopter-only commands
//! (`export`, `closed-loop`) give a model whose signals are named otherwise.

use kestrel_core::formats::SsModel;
use kestrel_tricopter_model::INPUT_NAMES;
use std::path::Path;

/// The rate outputs the tricopter's loop measures, in order.
const RATE_OUTPUTS: [&str; 3] = ["p", "q", "r"];

/// Whether the model's inputs are named `pwm1, pwm2, pwm3, servo`.
pub fn has_tricopter_inputs(model: &SsModel) -> bool {
    model
        .inputs
        .as_ref()
        .is_some_and(|v| v.iter().map(String::as_str).eq(INPUT_NAMES))
}

/// A model whose inputs or outputs are named otherwise than the
/// tricopter's (a quadrotor's four motors, say) is used as asked, with a
/// note on standard error saying how `user` (e.g. "the example firmware")
/// drives and reads it; unnamed signals get no note.
pub fn note_if_not_the_tricopter(model: &SsModel, path: &Path, user: &str) {
    let differs = |names: &Option<Vec<String>>, want: &[&str]| {
        names
            .as_ref()
            .filter(|n| n.iter().map(String::as_str).ne(want.iter().copied()))
            .map(|n| n.join(", "))
    };
    if let Some(names) = differs(&model.inputs, &INPUT_NAMES) {
        eprintln!(
            "note: {}: the model's inputs are {names}, not the tricopter's {}; {user} drives its inputs as motors 1-3 (us) and the tail servo (us around 1500), in that order",
            path.display(),
            INPUT_NAMES.join(", ")
        );
    }
    if let Some(names) = differs(&model.outputs, &RATE_OUTPUTS) {
        eprintln!(
            "note: {}: the model's outputs are {names}; {user} feeds it the gyro's p, q, r (rad/s), in that order",
            path.display()
        );
    }
}
