//! Host-side table generator for the example firmware (design time, f64).
//!
//! ```sh
//! cargo run -p kestrel-avr-rt --example avr_tables   # writes avr/firmware/src/generated.rs
//! ```
//!
//! Pipeline (no identified model is available yet from kestrel-sysid's
//! pipeline, so the design model is kestrel-tricopter-model's):
//! 1. kestrel-mpc's design model: the 8-state rates-plus-actuators
//!    linearisation of the default aircraft at hover, 50 Hz (`c2d` inside
//!    kestrel-tricopter-model), `[p, q, r, w1, w2, w3, alpha, alpha_dot]`,
//!    reduced to the thesis's **5 states** `[p, q, r, alpha, alpha_dot]` by
//!    singular perturbation of the three motor-speed states (DC matched).
//!    (kestrel-sysid's balanced reduction needs a stable model; the rate
//!    states have poles at 1, so it refuses this one);
//! 2. the stationary Kalman filter of kestrel-kalman (kestrel-mpc's
//!    closed-loop noise design: `G = [B, C']`, thesis gyro covariance (7.6)
//!    and bias (7.5));
//! 3. the thesis-sized MPC problem of kestrel-mpc (N = 2, Ns = 1, 4 inputs,
//!    throttle-dependent bounds) on the 5-state model;
//! 4. kestrel-fgm: optimal diagonal preconditioning and the cold-start
//!    certificate for the eps that keeps every input within 1 us of the
//!    optimum, folded for f32 and for Q16 (box shrunk by the rounding bound).
//!
//! The HIL test (`tests/hil.rs`) includes this file, checks that the
//! committed `generated.rs` is what this design produces, and flies the
//! firmware against the host f64 filter and solver.

use kestrel_core::formats::SsModel;
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::{BoxQp, Certificate, FgmData, FgmDesign, FgmSettings, Preconditioner};
use kestrel_kalman::{KalmanDesign, StationaryGains};
use kestrel_mpc::{
    MpcProblem, ProblemSize, TricopterTrim, default_weights, design_model, tricopter_problem,
    tricopter_trim,
};
use nalgebra::DMatrix;
use std::fmt::Write as _;

/// States of the firmware's model (the thesis's black-box order).
pub const NX: usize = 5;
/// Decision variables of the thesis-sized problem (N = 2, Ns = 1, 4 inputs).
pub const NZ: usize = 4;
/// Parameters: 5 states, 3 rate references, the throttle.
pub const NP: usize = NX + 4;
/// Iterations the firmware runs per period (warm-started): the certified
/// cold-start count does not fit the 20 ms period on the ATmega2560 (see
/// the crate README), so the loop runs this budget, like the thesis's 12.
pub const LOOP_ITERATIONS: usize = 20;

/// Everything the firmware tables are made of, in f64.
pub struct AvrDesign {
    /// The 5-state 50 Hz design model.
    pub model: SsModel,
    /// The stationary filter design.
    pub kalman: KalmanDesign,
    /// Run-time filter tables, inputs taken as moves from the trim (`u0 = 0`).
    pub gains: StationaryGains<f64, NX, 4, 3>,
    /// The thesis-sized problem.
    pub problem: MpcProblem,
    /// Its box-QP form.
    pub qp: BoxQp,
    /// The fast-gradient design.
    pub fgm: FgmDesign,
    /// The 1 us certificate.
    pub cert: Certificate,
    /// The eps used.
    pub eps: f64,
    /// Folded solver data in f64, f32 and Q16.
    pub data_f64: FgmData<f64>,
    /// f32 data.
    pub data_f32: FgmData<f32>,
    /// Q16 data.
    pub data_q16: FgmData<Q16>,
    /// Hover trim.
    pub trim: TricopterTrim,
}

/// Singular perturbation (discrete, DC matched): the `fast` states are set
/// to their steady state `x2 = (I - A22)^-1 (A21 x1 + B2 u)` and eliminated.
pub fn residualize(m: &SsModel, fast: &[usize]) -> SsModel {
    let n = m.nx();
    let slow: Vec<usize> = (0..n).filter(|i| !fast.contains(i)).collect();
    let pick = |mat: &DMatrix<f64>, rows: &[usize], cols: &[usize]| {
        DMatrix::from_fn(rows.len(), cols.len(), |i, j| mat[(rows[i], cols[j])])
    };
    let all_u: Vec<usize> = (0..m.nu()).collect();
    let all_y: Vec<usize> = (0..m.ny()).collect();
    let a11 = pick(&m.a, &slow, &slow);
    let a12 = pick(&m.a, &slow, fast);
    let a21 = pick(&m.a, fast, &slow);
    let a22 = pick(&m.a, fast, fast);
    let b1 = pick(&m.b, &slow, &all_u);
    let b2 = pick(&m.b, fast, &all_u);
    let c1 = pick(&m.c, &all_y, &slow);
    let c2 = pick(&m.c, &all_y, fast);
    let inv = (DMatrix::identity(fast.len(), fast.len()) - a22)
        .try_inverse()
        .expect("fast states without a pole at 1");
    let mut r = SsModel::new(
        m.ts,
        &a11 + &a12 * &inv * &a21,
        &b1 + &a12 * &inv * &b2,
        &c1 + &c2 * &inv * &a21,
        &m.d + &c2 * &inv * &b2,
    )
    .expect("reduced model");
    r.u0 = m.u0.clone();
    r.y0 = m.y0.clone();
    r
}

/// Runs the design pipeline.
pub fn design() -> AvrDesign {
    let full = design_model().expect("design model");
    let model = residualize(&full, &[3, 4, 5]);
    let kalman = kestrel_mpc::sim::kalman_design(&model).expect("Kalman design");
    let mut gains = kalman.gains::<f64, NX, 4, 3>().expect("gains");
    // The firmware feeds the filter the move from the trim (what the law
    // returns), i.e. `u - u0`; the measurement offset keeps `y0` only, the
    // bias is removed by the loop's bias stage.
    gains.u0 = [0.0; 4];
    gains.y_offset = gains.y0;
    let (q1, q2) = default_weights();
    let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).expect("problem");
    let qp = BoxQp::from_mpqp(&problem.to_mpqp()).expect("box QP");
    let fgm = FgmDesign::new(
        qp.clone(),
        FgmSettings {
            preconditioner: Preconditioner::OptimalDiagonal,
            ..FgmSettings::default()
        },
    )
    .expect("fgm design");
    let eps = kestrel_fgm::eps_for_input_error(fgm.preconditioning.before.mu, 1.0);
    let cert = fgm.certify(eps).expect("certificate");
    let data_f64 = fgm.data::<f64>(&cert, None).expect("f64 data");
    let data_f32 = fgm.data::<f32>(&cert, None).expect("f32 data");
    let data_q16 = fgm.data::<Q16>(&cert, None).expect("Q16 data");
    let trim = tricopter_trim(&model).expect("trim");
    AvrDesign {
        model,
        kalman,
        gains,
        problem,
        qp,
        fgm,
        cert,
        eps,
        data_f64,
        data_f32,
        data_q16,
        trim,
    }
}

/// The flat table: Kalman `A, B, C, M, y_offset`, the solver's `M, K, k0,
/// lo_theta, lo0, hi_theta, hi0, d, d_inv, betas`, mixer offsets, gyro bias.
fn flat<S: Scalar>(
    g: &StationaryGains<f64, NX, 4, 3>,
    d: &FgmData<S>,
    mix: &[f64; 4],
    bias: &[f64; 3],
) -> Vec<S> {
    let mut v: Vec<S> = Vec::new();
    let g = g.cast::<S>();
    for row in g.a.data.iter() {
        v.extend_from_slice(row);
    }
    for row in g.b.data.iter() {
        v.extend_from_slice(row);
    }
    for row in g.c.data.iter() {
        v.extend_from_slice(row);
    }
    for row in g.m.data.iter() {
        v.extend_from_slice(row);
    }
    v.extend_from_slice(&g.y_offset);
    for part in [
        &d.m,
        &d.k_theta,
        &d.k0,
        &d.lo_theta,
        &d.lo0,
        &d.hi_theta,
        &d.hi0,
        &d.d,
        &d.d_inv,
        &d.betas,
    ] {
        v.extend_from_slice(part);
    }
    v.extend(mix.iter().map(|x| S::from_f64(*x)));
    v.extend(bias.iter().map(|x| S::from_f64(*x)));
    v
}

impl AvrDesign {
    /// Mixer offsets: motor trims from the throttle, servo centre plus trim.
    pub fn mixer_offset(&self) -> [f64; 4] {
        let o = self.trim.offsets;
        [o[0], o[1], o[2], kestrel_mpc::pwm::SERVO_CENTER + o[3]]
    }

    /// The gyro bias removed by the loop.
    pub fn bias(&self) -> [f64; 3] {
        [
            self.kalman.bias[0],
            self.kalman.bias[1],
            self.kalman.bias[2],
        ]
    }

    /// The generated Rust source of `avr/firmware/src/generated.rs`.
    pub fn rust_source(&self) -> String {
        let mix = self.mixer_offset();
        let bias = self.bias();
        let f = flat(&self.gains, &self.data_f32, &mix, &bias);
        let q = flat(&self.gains, &self.data_q16, &mix, &bias);
        let t = self.data_f32.betas.len();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "// @generated by `cargo run -p kestrel-avr-rt --example avr_tables`; do not edit.\n\
             //\n\
             // Design model: kestrel-mpc's 8-state linearisation of kestrel-tricopter-model's\n\
             // default aircraft (50 Hz), motor states residualised (DC matched): {NX} states\n\
             // [p, q, r, alpha, alpha_dot].\n\
             // Stationary Kalman filter: kestrel-kalman (75 multiply-adds).\n\
             // Fast gradient: kestrel-fgm, thesis-sized problem (N = 2, Ns = 1, 4 inputs),\n\
             // eps = {:.6e} (1 us input error), condition {:.3e}, {:?} momentum,\n\
             // certified cold-start iterations {}.\n",
            self.eps, self.cert.condition, self.cert.scheme, self.cert.iterations
        );
        let _ = writeln!(
            s,
            "/// States of the design model.\npub const NX: usize = {NX};"
        );
        let _ = writeln!(
            s,
            "/// Solver decision variables.\npub const NZ: usize = {NZ};"
        );
        let _ = writeln!(s, "/// Solver parameters.\npub const NP: usize = {NP};");
        let _ = writeln!(
            s,
            "/// Momentum table length.\npub const FGM_T: usize = {t};"
        );
        let _ = writeln!(
            s,
            "/// Certified cold-start iterations.\npub const FGM_ITERATIONS: usize = {};",
            self.cert.iterations
        );
        let _ = writeln!(
            s,
            "/// Iterations run per period (warm start; not certified).\npub const FGM_LOOP_ITERATIONS: usize = {};",
            LOOP_ITERATIONS.min(self.cert.iterations)
        );
        let _ = writeln!(
            s,
            "/// Number of table values.\npub const N_VALUES: usize = {};",
            f.len()
        );
        let offs = [
            ("KF_A", NX * NX),
            ("KF_B", NX * 4),
            ("KF_C", 3 * NX),
            ("KF_M", NX * 3),
            ("KF_Y0", 3),
            ("FGM_M", NZ * NZ),
            ("FGM_K", NZ * NP),
            ("FGM_K0", NZ),
            ("FGM_LO", NZ * NP),
            ("FGM_LO0", NZ),
            ("FGM_HI", NZ * NP),
            ("FGM_HI0", NZ),
            ("FGM_D", NZ),
            ("FGM_DINV", NZ),
            ("FGM_BETAS", t),
            ("MIX_OFFSET", 4),
            ("BIAS", 3),
        ];
        let mut at = 0;
        for (name, len) in offs {
            let _ = writeln!(
                s,
                "/// Offset of `{name}` in the table.\npub const {name}: usize = {at};"
            );
            at += len;
        }
        assert_eq!(at, f.len());
        let _ = writeln!(
            s,
            "/// The table in f32.\n#[rustfmt::skip]\npub const VALUES_F32: [f32; N_VALUES] = ["
        );
        for c in f.chunks(6) {
            let line: Vec<String> = c.iter().map(|v| format!("{:e}", *v)).collect();
            let _ = writeln!(s, "    {},", line.join(", "));
        }
        let _ = writeln!(
            s,
            "];\n/// The table in Q16 (raw bits).\n#[rustfmt::skip]\npub const VALUES_Q16: [i32; N_VALUES] = ["
        );
        for c in q.chunks(8) {
            let line: Vec<String> = c.iter().map(|v| format!("{}", v.0)).collect();
            let _ = writeln!(s, "    {},", line.join(", "));
        }
        let _ = writeln!(s, "];");
        s
    }
}

/// Path of the generated file.
pub fn generated_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../avr/firmware/src/generated.rs")
}

#[allow(dead_code)]
fn main() {
    let d = design();
    let src = d.rust_source();
    let path = generated_path();
    std::fs::write(&path, src).expect("write generated.rs");
    println!(
        "wrote {}: {} states, Kalman {} MACs, fgm eps {:.3e}, {} iterations ({:?}), condition {:.3e}",
        path.display(),
        NX,
        d.gains.multiply_adds(),
        d.eps,
        d.cert.iterations,
        d.cert.scheme,
        d.cert.condition
    );
}
