//! Whether the firmware's design files belong together: the Kalman
//! filter's model against the design model, the MPC problem's model against
//! the filter's (issue 20, finding 4).
//!
//! The firmware feeds the filter's state estimate to the MPC law as the
//! leading part of its parameter `theta`, so the filter and the problem
//! must run the same model in the same state coordinates; equal sizes are
//! not enough. A `kestrel.kalman.v1` file carries its model (`ts`, `A`,
//! `B`, `C`, `D`, `u0`), which is compared with the design model entry by
//! entry; it may be the design model augmented with constant disturbance
//! states (the offset-free MPC's estimator: rows `[0, I]` of `A`, zero rows
//! of `B`), whose plant part must be the design model. A `kestrel.mpqp.v1`
//! file carries the model it was built on only as its optional
//! `model_fingerprint` ([`MpqpProblem::model_fingerprint`]), which must be
//! that of the filter's model; without it only the sizes can be checked.

use crate::firmware::error::{DesignError, DesignPart};
use crate::firmware::settings::NR;
use kestrel_core::formats::{FormatError, MpqpProblem, SsModel, json};
use kestrel_kalman::KalmanDesign;
use nalgebra::DMatrix;

/// A condensed MPC problem and the fingerprint of the model it was built
/// on (the optional `model_fingerprint` key of `kestrel.mpqp.v1`).
#[derive(Clone, Debug, PartialEq)]
pub struct ProblemFile {
    /// The problem.
    pub problem: MpqpProblem,
    /// [`MpqpProblem::model_fingerprint`] of its model, if the file has one.
    pub model_fingerprint: Option<String>,
}

impl ProblemFile {
    /// Reads a `kestrel.mpqp.v1` text and its model fingerprint.
    ///
    /// # Errors
    /// The format's errors.
    pub fn from_json_str(text: &str) -> Result<Self, FormatError> {
        let obj = json::parse_object(text)?;
        Ok(ProblemFile {
            problem: MpqpProblem::from_object(&obj)?,
            model_fingerprint: MpqpProblem::model_fingerprint_of(&obj)?,
        })
    }

    /// Reads a `kestrel.mpqp.v1` file and its model fingerprint.
    ///
    /// # Errors
    /// The file's and the format's errors.
    pub fn read(path: &std::path::Path) -> Result<Self, FormatError> {
        Self::from_json_str(&kestrel_core::formats::read_text(path)?)
    }
}

/// How far the MPC problem could be checked against the filter's model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProblemCheck {
    /// Its model fingerprint is that of the filter's model.
    Fingerprint,
    /// It carries no model fingerprint: only its sizes were checked.
    SizesOnly,
    /// It was built here from the design model.
    BuiltHere,
}

/// What [`FirmwareDesign::from_parts`](crate::firmware::FirmwareDesign::from_parts) found.
#[derive(Clone, Debug, PartialEq)]
pub struct Consistency {
    /// Disturbance states of the filter beyond the design model's.
    pub disturbance_states: usize,
    /// How far the problem was checked.
    pub problem: ProblemCheck,
}

fn mismatch(first: DesignPart, second: DesignPart, detail: String) -> DesignError {
    DesignError::Mismatch {
        first,
        second,
        detail,
    }
}

/// The largest difference of two equal-shaped matrices beyond a relative
/// tolerance of `1e-9` of `scale`, described as `name[i][j]`.
fn difference(
    name: &str,
    filter: &DMatrix<f64>,
    model: &DMatrix<f64>,
    scale: f64,
) -> Option<String> {
    let (mut worst, mut at) = (0.0, (0, 0));
    for i in 0..model.nrows() {
        for j in 0..model.ncols() {
            let d = (filter[(i, j)] - model[(i, j)]).abs();
            if d > worst || d.is_nan() {
                (worst, at) = (d, (i, j));
            }
        }
    }
    let scale = scale.max(filter.amax()).max(model.amax());
    // NaN differences are not close either.
    let close = worst <= 1e-9 * scale;
    (!close).then(|| {
        let (i, j) = at;
        format!(
            "{name}[{i}][{j}] is {} in the filter and {} in the model (largest difference {worst:.3e})",
            filter[(i, j)],
            model[(i, j)]
        )
    })
}

/// The model the filter runs, checked against the design model: the
/// design model itself when the filter has its states, or the design model
/// with the filter's disturbance states (`nx + nd` states: `A = [A, Bd; 0,
/// I]`, `B = [B; 0]`, `C = [C, Cd]`, the design model's operating point and
/// names). Returns it and `nd`.
///
/// The filter's sample time, `A`, `B`, `C`, `D` (its plant part when
/// augmented) and `u0` must be the model's to within `1e-9` relative;
/// `y0` is not compared (a filter that removes a sensor bias keeps the rest
/// of the offset there).
///
/// # Errors
/// [`DesignError::Mismatch`] (Kalman filter, design model) saying what differs.
pub fn estimator_model(
    model: &SsModel,
    kalman: &KalmanDesign,
) -> Result<(SsModel, usize), DesignError> {
    let differ = |detail: String| mismatch(DesignPart::Kalman, DesignPart::Model, detail);
    let (nx, nk) = (model.nx(), kalman.nx());
    if (kalman.nu(), kalman.ny()) != (model.nu(), model.ny()) {
        return Err(differ(format!(
            "the filter has {} inputs and {} outputs, the model {} and {}",
            kalman.nu(),
            kalman.ny(),
            model.nu(),
            model.ny()
        )));
    }
    if nk < nx {
        return Err(differ(format!(
            "the filter has {nk} states, fewer than the model's {nx}"
        )));
    }
    let same_ts = (kalman.ts - model.ts).abs() <= 1e-9 * model.ts.abs();
    if !same_ts {
        return Err(differ(format!(
            "the filter's sample time is {} s, the model's {} s",
            kalman.ts, model.ts
        )));
    }
    let nd = nk - nx;
    let part =
        |m: &DMatrix<f64>, rows: usize, cols: usize| m.view((0, 0), (rows, cols)).into_owned();
    let (ny, nu) = (model.ny(), model.nu());
    let model_u0 = match &model.u0 {
        Some(u) => DMatrix::from_row_slice(1, nu, u.as_slice()),
        None => DMatrix::zeros(1, nu),
    };
    let markov = model.c.amax() * model.b.amax();
    let checks = [
        ("A", part(&kalman.a, nx, nx), &model.a, 0.0),
        ("B", part(&kalman.b, nx, nu), &model.b, 0.0),
        ("C", part(&kalman.c, ny, nx), &model.c, 0.0),
        ("D", kalman.d.clone(), &model.d, markov),
        (
            "u0",
            DMatrix::from_row_slice(1, nu, kalman.u0.as_slice()),
            &model_u0,
            0.0,
        ),
    ];
    for (name, filter, model_m, scale) in &checks {
        if let Some(what) = difference(name, filter, model_m, *scale) {
            let whose = if nd > 0 {
                format!(
                    "the filter's plant part (its first {nx} of {nk} states) is not the model: "
                )
            } else {
                "the filter was designed for another model: ".into()
            };
            return Err(differ(format!("{whose}{what}")));
        }
    }
    if nd == 0 {
        return Ok((model.clone(), 0));
    }
    // The disturbance states are constant: rows [0, I] of A, zero rows of B.
    if !kestrel_kalman::augment::integrating_disturbances(&kalman.a, &kalman.b, nd) {
        return Err(differ(format!(
            "the filter has {nk} states, the model {nx}, and its last {nd} are not constant disturbance states (rows [0, I] of A, zero rows of B)"
        )));
    }
    let mut est = SsModel::new(
        model.ts,
        kalman.a.clone(),
        kalman.b.clone(),
        kalman.c.clone(),
        kalman.d.clone(),
    )
    .map_err(|e| DesignError::Unsupported(format!("the filter's model: {e}")))?;
    est.u0 = model.u0.clone();
    est.y0 = model.y0.clone();
    est.inputs = model.inputs.clone();
    est.outputs = model.outputs.clone();
    Ok((est, nd))
}

/// Checks an MPC problem against the filter's model `estimator` (from
/// [`estimator_model`]; `nd` of its states are disturbance states): its
/// parameters must be that model's states, the three rate references and
/// the throttle, and its model fingerprint, when it has one, that model's.
///
/// # Errors
/// [`DesignError::Mismatch`] (MPC problem, Kalman filter) for parameters
/// that are not the filter's states; (MPC problem, design model or Kalman
/// filter when `nd > 0`) for another model's fingerprint.
pub fn check_problem(
    estimator: &SsModel,
    nd: usize,
    problem: &ProblemFile,
) -> Result<ProblemCheck, DesignError> {
    let nx = estimator.nx();
    let p = problem.problem.p();
    if p != nx + NR {
        let fingerprint_matches = problem
            .model_fingerprint
            .as_ref()
            .is_some_and(|f| *f == MpqpProblem::model_fingerprint(estimator));
        let hint = if p + 1 == nx + NR && fingerprint_matches {
            "; it was built on this model without the throttle, the example firmware's last parameter (theta = [x; p_ref, q_ref, r_ref; throttle])".to_string()
        } else if p > NR {
            format!(
                "; the problem is for {} states{}",
                p - NR,
                if p - NR > nx {
                    " (a model with disturbance states: give the filter designed on it)"
                } else {
                    ""
                }
            )
        } else {
            String::new()
        };
        return Err(mismatch(
            DesignPart::Problem,
            DesignPart::Kalman,
            format!(
                "the problem has {p} parameters, the filter's {nx} states + 3 rate references + throttle are {}{hint}",
                nx + NR
            ),
        ));
    }
    let Some(found) = &problem.model_fingerprint else {
        return Ok(ProblemCheck::SizesOnly);
    };
    let want = MpqpProblem::model_fingerprint(estimator);
    if *found != want {
        let (second, whose) = if nd > 0 {
            (
                DesignPart::Kalman,
                "the filter's model (the design model with its disturbance states)",
            )
        } else {
            (DesignPart::Model, "the model")
        };
        return Err(mismatch(
            DesignPart::Problem,
            second,
            format!(
                "the problem was built on another model: its {} is {found}, {whose} has {want} (the problem's parameters start with its model's states)",
                MpqpProblem::MODEL_FINGERPRINT_KEY
            ),
        ));
    }
    Ok(ProblemCheck::Fingerprint)
}
