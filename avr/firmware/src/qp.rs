//! The `qp` builds' set-up: kestrel-qp's solver in f32 on the box QP of
//! `src/generated_qp.rs`, the law of `src/qp_law.rs`.

use crate::generated_qp::*;
use crate::qp_law::{QpLaw, QpMaps};
use kestrel_qp::{QpSettings, QpSolver, index_len, scalar_len};

/// The law of the `qp` builds.
pub type Law<'w> = QpLaw<'w, f32, QP_N, QP_P, 4>;

/// kestrel-qp's settings in the `qp` builds: f32 tolerances with the
/// primal one in the problem's units (microseconds of PWM: 1e-3 us, above
/// f32's rounding of a 2,000 us bound) and the iteration cap: 8
/// active-set changes, the certified worst case of the design's problem
/// over its parameter box (kestrel-empc's certification: 6 from a cold
/// start, 8 from a warm start for parameter steps up to 5 % of the box's
/// width; checked by the HIL test `qp_certified`), so that only a period
/// beyond the certificate (a larger step) takes the fallback, and a solve
/// is bounded in time (docs/avr-rt.md); 1 in the `qp-fallback-test` build.
pub const SETTINGS: QpSettings = QpSettings {
    primal_tol: 1e-3,
    dual_tol: 1e-6,
    pivot_tol: 1e-5,
    max_iterations: if cfg!(feature = "qp-fallback-test") {
        1
    } else {
        8
    },
};

/// Whether each solve starts from the previous period's active set (not
/// in the `qp-fallback-test` build, which starts every solve cold).
pub const WARM: bool = !cfg!(feature = "qp-fallback-test");

/// The solver's workspaces (`scalar_len(4, 0)` f32, `index_len(4, 0)`
/// indices: 344 + 28 bytes).
pub struct Workspace {
    scalars: [f32; scalar_len(QP_N, 0)],
    indices: [usize; index_len(QP_N, 0)],
}

impl Workspace {
    /// Zeroed workspaces.
    pub const fn new() -> Self {
        Workspace {
            scalars: [0.0; scalar_len(QP_N, 0)],
            indices: [0; index_len(QP_N, 0)],
        }
    }
}

/// The law on `ws` with `settings`, reading `nx` states; `None` if the
/// solver or the law refuses the tables.
pub fn law(ws: &mut Workspace, settings: QpSettings, warm: bool, nx: usize) -> Option<Law<'_>> {
    let h: [f32; QP_N * QP_N] = core::array::from_fn(|k| QP_H[k / QP_N][k % QP_N]);
    let solver =
        QpSolver::new(QP_N, 0, &h, &[], settings, &mut ws.scalars, &mut ws.indices).ok()?;
    let maps = QpMaps {
        f: &QP_F,
        f0: &QP_F0,
        lo: &QP_LO,
        lo0: &QP_LO0,
        hi: &QP_HI,
        hi0: &QP_HI0,
        hinv: &QP_HINV,
    };
    QpLaw::new(solver, maps, nx, warm).ok()
}
