//! The `qp` builds' set-up (kestrel-qp's solver in f32 on the box QP of
//! `src/generated_qp.rs`, the law of `src/qp_law.rs`) and, with
//! `qp-check`, the on-target check at pseudo-random parameters.

use crate::generated_qp::*;
use crate::qp_law::{QpLaw, QpMaps};
use kestrel_qp::{QpSettings, QpSolver, index_len, scalar_len};

/// The law of the `qp` builds.
pub type Law<'w> = QpLaw<'w, f32, QP_N, QP_P, 4>;

/// kestrel-qp's settings in the `qp` builds: f32 tolerances with the
/// primal one in the problem's units (microseconds of PWM: 1e-3 us, above
/// f32's rounding of a 2,000 us bound) and the iteration cap: 16
/// active-set changes (a cold solve of the 4-variable box QP ends after 4
/// additions when nothing is removed; the certified worst case is in
/// docs/avr-rt.md), 1 in the `qp-fallback-test` build.
pub const SETTINGS: QpSettings = QpSettings {
    primal_tol: 1e-3,
    dual_tol: 1e-6,
    pivot_tol: 1e-5,
    max_iterations: if cfg!(feature = "qp-fallback-test") {
        1
    } else {
        16
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

/// Parameters of each part of [`check`].
#[cfg(feature = "qp-check")]
pub const CHECK_SAMPLES: u16 = 150;

/// The on-target check (feature `qp-check`), three parts of
/// [`CHECK_SAMPLES`] solves of the whole law (`ControlLaw::control`:
/// set-up of `q` and the box, solve, first move):
///
/// 1. cold starts at pseudo-random parameters in the parameter box;
/// 2. warm starts along a random walk in the box (each step at most 5 % of
///    the box's width per parameter);
/// 3. a second law with the iteration cap 1 and cold starts at
///    pseudo-random parameters: the fallback (the unconstrained optimum
///    clamped to the box) wherever two or more active-set changes are
///    needed.
///
/// Per solve it sends two Bench-kind frames through `send`: the index and
/// the parameter's nine f32 (38 bytes), then the index, the law's
/// iterations (with `FALLBACK`), the cycles and the four f32 outputs (24
/// bytes); the HIL test solves the same parameters on the host.
#[cfg(feature = "qp-check")]
#[inline(never)] // its own frame, not main's
pub fn check(
    law: &mut Law<'_>,
    nx: usize,
    clock: &impl kestrel_avr_rt::cycles::CycleClock,
    send: &mut dyn FnMut(&[u8]),
) {
    use kestrel_avr_rt::control::LawInfo;
    let mut seed = 0x2545_f491u32;
    let mut uniform = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 // [0, 1)
    };
    let mut ws = Workspace::new();
    let Some(mut capped) = self::law(
        &mut ws,
        QpSettings {
            max_iterations: 1,
            ..SETTINGS
        },
        false,
        nx,
    ) else {
        return;
    };
    let mut theta = [0f32; QP_P];
    for i in 0..3 * CHECK_SAMPLES {
        let part = i / CHECK_SAMPLES;
        for (j, t) in theta.iter_mut().enumerate() {
            let (lo, hi) = (QP_THETA_LB[j], QP_THETA_UB[j]);
            *t = if part == 1 && i > CHECK_SAMPLES {
                (*t + (hi - lo) * 0.05 * (2.0 * uniform() - 1.0)).clamp(lo, hi)
            } else {
                lo + (hi - lo) * uniform()
            };
        }
        if part == 0 || i == CHECK_SAMPLES {
            law.restart();
        }
        let mut a = [0u8; 2 + 4 * QP_P];
        a[0..2].copy_from_slice(&i.to_le_bytes());
        for (j, t) in theta.iter().enumerate() {
            a[2 + 4 * j..6 + 4 * j].copy_from_slice(&t.to_le_bytes());
        }
        send(&a);
        let (iterations, cycles, u) = if part == 2 {
            solve_one(&mut capped, &theta, nx, clock)
        } else {
            solve_one(law, &theta, nx, clock)
        };
        let mut b = [0u8; 24];
        b[0..2].copy_from_slice(&i.to_le_bytes());
        b[2..4].copy_from_slice(&iterations.to_le_bytes());
        b[4..8].copy_from_slice(&cycles.to_le_bytes());
        for (k, v) in u.iter().enumerate() {
            b[8 + 4 * k..12 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
        send(&b);
    }
}

/// One timed call of `law` at `theta`: its iterations (0xFFFF for an
/// error), cycles and outputs.
#[cfg(feature = "qp-check")]
#[inline(never)]
fn solve_one(
    law: &mut Law<'_>,
    theta: &[f32; QP_P],
    nx: usize,
    clock: &impl kestrel_avr_rt::cycles::CycleClock,
) -> (u16, u32, [f32; 4]) {
    use kestrel_avr_rt::control::LawInfo;
    use kestrel_core::ControlLaw;
    let th = core::hint::black_box(*theta);
    let mut u = [0f32; 4];
    let t0 = clock.now();
    let r = core::hint::black_box(law.control(&th[..nx], &th[nx..], &mut u));
    let cycles = clock.now().wrapping_sub(t0);
    let iterations = if r.is_ok() { law.iterations() } else { 0xFFFF };
    (iterations, cycles, u)
}
