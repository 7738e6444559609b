//! The nonlinear tricopter model: rigid body (3.11)-(3.21) in a North-East-Down
//! world frame with a Front-Right-Down body frame, plus first-order motors and
//! a second-order tail servo; outputs (3.22); fixed-step RK4; analytic
//! Jacobians.
//!
//! Differences from the printed thesis (see `ERRATA.md`):
//! - world frame NED instead of North-West-Up, so hover is at zero roll and
//!   gravity is `+g` along world z; altitude is `-z`;
//! - the rotation is the corrected (3.3): `Q = Qx(phi) Qy(theta) Qz(psi)`
//!   maps world to body, so body forces go to the world frame with `Q^T`;
//! - (3.2b) without the extra `pi/180`; latitude and longitude relative to
//!   the origin in [`Params`];
//! - each rotor's reaction torque carries a spin sign (`Params::spin`);
//! - the motor and servo dynamics of (3.5)-(3.9) are states, not neglected.

use crate::error::ModelError;
use crate::params::{Params, R_EARTH};
use nalgebra::SMatrix;

/// Number of states: 12 rigid-body states, 3 rotor speeds, servo angle and rate.
pub const NX: usize = 17;
/// Number of inputs: three ESC pulses and the servo pulse (us).
pub const NU: usize = 4;
/// Number of outputs of (3.22): latitude, longitude, altitude, |V|, heading, p, q, r.
pub const NY: usize = 8;

/// The full state `x` (see [`idx`] for the meaning of each entry).
pub type State = [f64; NX];
/// The input `u = [pwm1, pwm2, pwm3, servo]` in microseconds.
pub type Input = [f64; NU];
/// The outputs `y = h(x)` of (3.22).
pub type Output = [f64; NY];

/// Indices into [`State`]. Units: m, m/s, rad, rad/s.
pub mod idx {
    /// North position (m, world NED).
    pub const X: usize = 0;
    /// East position (m).
    pub const Y: usize = 1;
    /// Down position (m); altitude is `-Z`.
    pub const Z: usize = 2;
    /// North velocity (m/s, world frame as in (3.11)).
    pub const VX: usize = 3;
    /// East velocity (m/s).
    pub const VY: usize = 4;
    /// Down velocity (m/s).
    pub const VZ: usize = 5;
    /// Roll angle `phi` (rad, Z-Y-X Euler angles).
    pub const PHI: usize = 6;
    /// Pitch angle `theta` (rad).
    pub const THETA: usize = 7;
    /// Yaw angle (heading) `psi` (rad).
    pub const PSI: usize = 8;
    /// Body roll rate `p` (rad/s, about body x = front).
    pub const P: usize = 9;
    /// Body pitch rate `q` (rad/s, about body y = right).
    pub const Q: usize = 10;
    /// Body yaw rate `r` (rad/s, about body z = down).
    pub const R: usize = 11;
    /// Speed of rotor 1 (rear, tilting) (rad/s).
    pub const W1: usize = 12;
    /// Speed of rotor 2 (front left) (rad/s).
    pub const W2: usize = 13;
    /// Speed of rotor 3 (front right) (rad/s).
    pub const W3: usize = 14;
    /// Tilt angle `alpha` of rotor 1 (rad, positive = thrust tilted to the right).
    pub const ALPHA: usize = 15;
    /// Tilt rate of rotor 1 (rad/s).
    pub const ALPHA_DOT: usize = 16;
}

/// Names of the states, in order (as used in `SsModel` files).
pub const STATE_NAMES: [&str; NX] = [
    "x",
    "y",
    "z",
    "vx",
    "vy",
    "vz",
    "phi",
    "theta",
    "psi",
    "p",
    "q",
    "r",
    "omega1",
    "omega2",
    "omega3",
    "alpha",
    "alpha_dot",
];
/// Names of the inputs, in order.
pub const INPUT_NAMES: [&str; NU] = ["pwm1", "pwm2", "pwm3", "servo"];
/// Names of the outputs of (3.22), in order.
pub const OUTPUT_NAMES: [&str; NY] = ["lat", "lng", "alt", "speed", "psi", "p", "q", "r"];

/// An external disturbance held constant over a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Disturbance {
    /// Force in the world frame (N), e.g. a wind gust.
    pub force: [f64; 3],
    /// Torque in the body frame (N m), e.g. a gust torque.
    pub torque: [f64; 3],
}

/// Jacobians of the model at an operating point (3.23).
#[derive(Clone, Debug, PartialEq)]
pub struct Linearization {
    /// `A = df/dx` (NX x NX).
    pub a: SMatrix<f64, NX, NX>,
    /// `B = df/du` (NX x NU), per microsecond; zero columns for saturated pulses.
    pub b: SMatrix<f64, NX, NU>,
    /// `C = dh/dx` (NY x NX). The `|V|` row is zero at zero velocity (where
    /// `|V|` is not differentiable).
    pub c: SMatrix<f64, NY, NX>,
    /// The state of the operating point.
    pub x0: State,
    /// The input of the operating point.
    pub u0: Input,
}

impl Linearization {
    /// The continuous-time model `dx' = A dx + B du`, `dy = C dx` as a
    /// `kestrel.ss.v1` model (`ts = 0`) with `x0`, `u0`, `y0 = h(x0)` and names.
    pub fn to_ss_model(&self, y0: &Output) -> Result<kestrel_core::formats::SsModel, ModelError> {
        use nalgebra::{DMatrix, DVector};
        let mut m = kestrel_core::formats::SsModel::new(
            0.0,
            DMatrix::from_fn(NX, NX, |i, j| self.a[(i, j)]),
            DMatrix::from_fn(NX, NU, |i, j| self.b[(i, j)]),
            DMatrix::from_fn(NY, NX, |i, j| self.c[(i, j)]),
            DMatrix::zeros(NY, NU),
        )?;
        m.x0 = Some(DVector::from_column_slice(&self.x0));
        m.u0 = Some(DVector::from_column_slice(&self.u0));
        m.y0 = Some(DVector::from_column_slice(y0));
        m.inputs = Some(INPUT_NAMES.iter().map(|s| s.to_string()).collect());
        m.outputs = Some(OUTPUT_NAMES.iter().map(|s| s.to_string()).collect());
        m.validate()?;
        Ok(m)
    }
}

const HALF_SQRT3: f64 = 0.866_025_403_784_438_6;

/// The tricopter: validated parameters plus precomputed constants.
///
/// ```
/// use kestrel_tricopter_model::{Params, Tricopter, idx};
/// let model = Tricopter::new(Params::default()).unwrap();
/// let trim = model.trim_hover().unwrap();
/// let mut x = trim.state;
/// for _ in 0..1000 {
///     model.step(&mut x, &trim.input, 1e-3).unwrap();   // 1 s at 1 kHz
/// }
/// assert!(x[idx::P].abs() < 1e-9 && x[idx::Z].abs() < 1e-9);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Tricopter {
    params: Params,
    inv_m: f64,
    inv_i: [f64; 3],
    gyro: [f64; 3],
    pwm_gain: f64,
    inv_tau: f64,
    wn2: f64,
    two_zeta_wn: f64,
}

/// Rotor forces and moments, and their partial derivatives.
struct Actuation {
    /// Body force (N).
    force: [f64; 3],
    /// Body moment (N m).
    moment: [f64; 3],
}

impl Tricopter {
    /// A model with validated parameters.
    pub fn new(params: Params) -> Result<Self, ModelError> {
        params.validate()?;
        let p = &params;
        Ok(Tricopter {
            params,
            inv_m: 1.0 / p.mass,
            inv_i: [1.0 / p.ixx, 1.0 / p.iyy, 1.0 / p.izz],
            gyro: [
                (p.iyy - p.izz) / p.ixx,
                (p.izz - p.ixx) / p.iyy,
                (p.ixx - p.iyy) / p.izz,
            ],
            pwm_gain: p.omega_max * 1e-3,
            inv_tau: 1.0 / p.motor_tau,
            wn2: p.servo_wn * p.servo_wn,
            two_zeta_wn: 2.0 * p.servo_zeta * p.servo_wn,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    #[inline]
    fn actuation(&self, x: &State) -> Actuation {
        let (sa, ca) = x[idx::ALPHA].sin_cos();
        self.actuation_trig(x, sa, ca)
    }

    #[inline]
    fn actuation_trig(&self, x: &State, sa: f64, ca: f64) -> Actuation {
        let p = &self.params;
        let (w1, w2, w3) = (x[idx::W1], x[idx::W2], x[idx::W3]);
        let (g1, g2, g3) = (w1 * w1.abs(), w2 * w2.abs(), w3 * w3.abs());
        let (f1, f2, f3) = (p.k_t * g1, p.k_t * g2, p.k_t * g3);
        let l = p.arm_length;
        let s = p.spin;
        Actuation {
            force: [0.0, f1 * sa, -(f1 * ca + f2 + f3)],
            moment: [
                HALF_SQRT3 * l * (f2 - f3),
                0.5 * l * (f2 + f3) - l * f1 * ca + s[0] * p.k_tau * g1 * sa,
                -l * f1 * sa - p.k_tau * (s[0] * g1 * ca + s[1] * g2 + s[2] * g3),
            ],
        }
    }

    /// `x' = f(x, u)` without disturbance.
    #[inline]
    pub fn derivative(&self, x: &State, u: &Input) -> State {
        self.derivative_with(x, u, &Disturbance::default())
    }

    /// `x' = f(x, u) + disturbance`.
    pub fn derivative_with(&self, x: &State, u: &Input, d: &Disturbance) -> State {
        self.derivative_targets(x, &self.actuator_targets(u), d)
    }

    /// Steady-state rotor speeds and commanded tilt for the (saturated) input.
    #[inline]
    fn actuator_targets(&self, u: &Input) -> [f64; 4] {
        let p = &self.params;
        [
            p.rotor_speed_for_pwm(u[0]),
            p.rotor_speed_for_pwm(u[1]),
            p.rotor_speed_for_pwm(u[2]),
            p.tilt_for_servo_pwm(u[3]),
        ]
    }

    #[inline]
    fn derivative_targets(&self, x: &State, tgt: &[f64; 4], d: &Disturbance) -> State {
        self.derivative_trig(x, &Trig::of(x), tgt, d)
    }

    #[inline]
    fn derivative_trig(&self, x: &State, tr: &Trig, tgt: &[f64; 4], d: &Disturbance) -> State {
        let act = self.actuation_trig(x, tr.s[3], tr.c[3]);
        let [sf, st, ss, _] = tr.s;
        let [cf, ct, cs, _] = tr.c;
        let q = rotation(sf, cf, st, ct, ss, cs);
        let (pr, qr, rr) = (x[idx::P], x[idx::Q], x[idx::R]);
        let mut dx = [0.0; NX];
        dx[idx::X] = x[idx::VX];
        dx[idx::Y] = x[idx::VY];
        dx[idx::Z] = x[idx::VZ];
        // Body force [0, Fy, Fz] to the world frame with Q^T.
        let fb = act.force;
        for i in 0..3 {
            let fw = q[1][i] * fb[1] + q[2][i] * fb[2];
            dx[idx::VX + i] = (fw + d.force[i]) * self.inv_m;
        }
        dx[idx::VZ] += self.params.gravity;
        let inv_ct = 1.0 / ct;
        let sq_cr = sf * qr + cf * rr;
        dx[idx::PHI] = pr + sq_cr * st * inv_ct;
        dx[idx::THETA] = cf * qr - sf * rr;
        dx[idx::PSI] = sq_cr * inv_ct;
        let m = act.moment;
        dx[idx::P] = self.gyro[0] * qr * rr + (m[0] + d.torque[0]) * self.inv_i[0];
        dx[idx::Q] = self.gyro[1] * pr * rr + (m[1] + d.torque[1]) * self.inv_i[1];
        dx[idx::R] = self.gyro[2] * pr * qr + (m[2] + d.torque[2]) * self.inv_i[2];
        for i in 0..3 {
            dx[idx::W1 + i] = (tgt[i] - x[idx::W1 + i]) * self.inv_tau;
        }
        dx[idx::ALPHA] = x[idx::ALPHA_DOT];
        dx[idx::ALPHA_DOT] =
            self.wn2 * (tgt[3] - x[idx::ALPHA]) - self.two_zeta_wn * x[idx::ALPHA_DOT];
        dx
    }

    /// One classical Runge-Kutta (RK4) step of length `dt` with the input
    /// held (zero-order hold). Allocation-free. Errors on a non-finite input,
    /// `dt` or resulting state (the state is then left unchanged).
    #[inline]
    pub fn step(&self, x: &mut State, u: &Input, dt: f64) -> Result<(), ModelError> {
        self.step_with(x, u, &Disturbance::default(), dt)
    }

    /// [`Tricopter::step`] with a disturbance held over the step.
    pub fn step_with(
        &self,
        x: &mut State,
        u: &Input,
        d: &Disturbance,
        dt: f64,
    ) -> Result<(), ModelError> {
        if !u.iter().all(|v| v.is_finite()) {
            return Err(ModelError::NonFinite { what: "input" });
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(ModelError::InvalidSetting {
                name: "dt",
                reason: format!("must be finite and positive, found {dt}"),
            });
        }
        let tgt = self.actuator_targets(u);
        let t0 = Trig::of(x);
        let k1 = self.derivative_trig(x, &t0, &tgt, d);
        let mut tmp = [0.0; NX];
        for i in 0..NX {
            tmp[i] = x[i] + 0.5 * dt * k1[i];
        }
        let k2 = self.derivative_trig(&tmp, &Trig::of(&tmp), &tgt, d);
        for i in 0..NX {
            tmp[i] = x[i] + 0.5 * dt * k2[i];
        }
        let k3 = self.derivative_trig(&tmp, &Trig::of(&tmp), &tgt, d);
        for i in 0..NX {
            tmp[i] = x[i] + dt * k3[i];
        }
        let k4 = self.derivative_trig(&tmp, &Trig::of(&tmp), &tgt, d);
        let h6 = dt / 6.0;
        for i in 0..NX {
            tmp[i] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        }
        if !tmp.iter().all(|v| v.is_finite()) {
            return Err(ModelError::NonFinite { what: "state" });
        }
        *x = tmp;
        Ok(())
    }

    /// Flat-ground contact at altitude 0: when the aircraft is at or below
    /// the ground and not climbing, it rests there (position clamped, the
    /// velocities, roll, pitch and body rates zeroed; heading, rotors and
    /// servo untouched). Returns whether it is on the ground.
    pub fn apply_ground(&self, x: &mut State) -> bool {
        if x[idx::Z] >= 0.0 && x[idx::VZ] >= 0.0 {
            x[idx::Z] = 0.0;
            for i in [
                idx::VX,
                idx::VY,
                idx::VZ,
                idx::PHI,
                idx::THETA,
                idx::P,
                idx::Q,
                idx::R,
            ] {
                x[i] = 0.0;
            }
            true
        } else {
            false
        }
    }

    /// The outputs `h(x)` of (3.22): latitude and longitude (degrees),
    /// altitude `-z` (m), `|V|` (m/s), heading `psi` (rad), `p, q, r` (rad/s).
    pub fn output(&self, x: &State) -> Output {
        let p = &self.params;
        let lat_rad = p.origin_lat_deg.to_radians() + x[idx::X] / R_EARTH;
        [
            lat_rad.to_degrees(),
            p.origin_lng_deg + (x[idx::Y] / (R_EARTH * lat_rad.cos())).to_degrees(),
            -x[idx::Z],
            (x[idx::VX].powi(2) + x[idx::VY].powi(2) + x[idx::VZ].powi(2)).sqrt(),
            x[idx::PSI],
            x[idx::P],
            x[idx::Q],
            x[idx::R],
        ]
    }

    /// Analytic Jacobians `A = df/dx`, `B = df/du`, `C = dh/dx` at `(x, u)`
    /// (3.23), for every operating point (not only hover; appendix B's
    /// printed entries are not used, see `ERRATA.md`). Checked against
    /// central finite differences in the tests.
    pub fn linearize(&self, x: &State, u: &Input) -> Linearization {
        let p = &self.params;
        let mut a = SMatrix::<f64, NX, NX>::zeros();
        let mut b = SMatrix::<f64, NX, NU>::zeros();
        let mut c = SMatrix::<f64, NY, NX>::zeros();
        let act = self.actuation(x);
        let (sf, cf) = x[idx::PHI].sin_cos();
        let (st, ct) = x[idx::THETA].sin_cos();
        let (ss, cs) = x[idx::PSI].sin_cos();
        let q = rotation(sf, cf, st, ct, ss, cs);
        let dq = rotation_partials(sf, cf, st, ct, ss, cs);
        let (pr, qr, rr) = (x[idx::P], x[idx::Q], x[idx::R]);

        // Position.
        for i in 0..3 {
            a[(idx::X + i, idx::VX + i)] = 1.0;
        }
        // Velocity: d(Q^T F)/d(angles) and d(Q^T F)/d(rotor states).
        let fb = act.force;
        for (k, dqk) in dq.iter().enumerate() {
            for i in 0..3 {
                let v = dqk[0][i] * fb[0] + dqk[1][i] * fb[1] + dqk[2][i] * fb[2];
                a[(idx::VX + i, idx::PHI + k)] = v * self.inv_m;
            }
        }
        // Partials of body force and moment w.r.t. [w1, w2, w3, alpha].
        let l = p.arm_length;
        let s = p.spin;
        let (kt, ktau) = (p.k_t, p.k_tau);
        let (w1, w2, w3) = (x[idx::W1], x[idx::W2], x[idx::W3]);
        let (dg1, dg2, dg3) = (2.0 * w1.abs(), 2.0 * w2.abs(), 2.0 * w3.abs());
        let g1 = w1 * w1.abs();
        let f1 = kt * g1;
        let (sa, ca) = x[idx::ALPHA].sin_cos();
        let df: [[f64; 3]; 4] = [
            [0.0, kt * dg1 * sa, -kt * dg1 * ca],
            [0.0, 0.0, -kt * dg2],
            [0.0, 0.0, -kt * dg3],
            [0.0, f1 * ca, f1 * sa],
        ];
        let dm: [[f64; 3]; 4] = [
            [
                0.0,
                -l * kt * dg1 * ca + s[0] * ktau * dg1 * sa,
                -l * kt * dg1 * sa - ktau * s[0] * dg1 * ca,
            ],
            [
                HALF_SQRT3 * l * kt * dg2,
                0.5 * l * kt * dg2,
                -ktau * s[1] * dg2,
            ],
            [
                -HALF_SQRT3 * l * kt * dg3,
                0.5 * l * kt * dg3,
                -ktau * s[2] * dg3,
            ],
            [
                0.0,
                l * f1 * sa + s[0] * ktau * g1 * ca,
                -l * f1 * ca + s[0] * ktau * g1 * sa,
            ],
        ];
        let act_cols = [idx::W1, idx::W2, idx::W3, idx::ALPHA];
        for (k, &col) in act_cols.iter().enumerate() {
            for i in 0..3 {
                let fw = q[0][i] * df[k][0] + q[1][i] * df[k][1] + q[2][i] * df[k][2];
                a[(idx::VX + i, col)] = fw * self.inv_m;
                a[(idx::P + i, col)] = dm[k][i] * self.inv_i[i];
            }
        }
        // Euler kinematics (3.20).
        let inv_ct = 1.0 / ct;
        let tt = st * inv_ct;
        let sq_cr = sf * qr + cf * rr;
        let cq_sr = cf * qr - sf * rr;
        a[(idx::PHI, idx::PHI)] = cq_sr * tt;
        a[(idx::PHI, idx::THETA)] = sq_cr * inv_ct * inv_ct;
        a[(idx::PHI, idx::P)] = 1.0;
        a[(idx::PHI, idx::Q)] = sf * tt;
        a[(idx::PHI, idx::R)] = cf * tt;
        a[(idx::THETA, idx::PHI)] = -sq_cr;
        a[(idx::THETA, idx::Q)] = cf;
        a[(idx::THETA, idx::R)] = -sf;
        a[(idx::PSI, idx::PHI)] = cq_sr * inv_ct;
        a[(idx::PSI, idx::THETA)] = sq_cr * st * inv_ct * inv_ct;
        a[(idx::PSI, idx::Q)] = sf * inv_ct;
        a[(idx::PSI, idx::R)] = cf * inv_ct;
        // Euler's equations (3.19): gyroscopic coupling.
        a[(idx::P, idx::Q)] = self.gyro[0] * rr;
        a[(idx::P, idx::R)] = self.gyro[0] * qr;
        a[(idx::Q, idx::P)] = self.gyro[1] * rr;
        a[(idx::Q, idx::R)] = self.gyro[1] * pr;
        a[(idx::R, idx::P)] = self.gyro[2] * qr;
        a[(idx::R, idx::Q)] = self.gyro[2] * pr;
        // Motors and servo.
        let inv_tau = 1.0 / p.motor_tau;
        for i in 0..3 {
            a[(idx::W1 + i, idx::W1 + i)] = -inv_tau;
            if u[i] > 1000.0 && u[i] < 2000.0 {
                b[(idx::W1 + i, i)] = self.pwm_gain * inv_tau;
            }
        }
        let wn2 = p.servo_wn * p.servo_wn;
        a[(idx::ALPHA, idx::ALPHA_DOT)] = 1.0;
        a[(idx::ALPHA_DOT, idx::ALPHA)] = -wn2;
        a[(idx::ALPHA_DOT, idx::ALPHA_DOT)] = -2.0 * p.servo_zeta * p.servo_wn;
        if u[3] > 1200.0 && u[3] < 1800.0 {
            b[(idx::ALPHA_DOT, 3)] = wn2 * p.servo_gain;
        }
        // Outputs (3.22).
        let lat_rad = p.origin_lat_deg.to_radians() + x[idx::X] / R_EARTH;
        let (sl, cl) = lat_rad.sin_cos();
        let deg = 180.0 / core::f64::consts::PI;
        c[(0, idx::X)] = deg / R_EARTH;
        c[(1, idx::X)] = deg * x[idx::Y] / R_EARTH * sl / (cl * cl) / R_EARTH;
        c[(1, idx::Y)] = deg / (R_EARTH * cl);
        c[(2, idx::Z)] = -1.0;
        let speed = (x[idx::VX].powi(2) + x[idx::VY].powi(2) + x[idx::VZ].powi(2)).sqrt();
        if speed > 0.0 {
            for i in 0..3 {
                c[(3, idx::VX + i)] = x[idx::VX + i] / speed;
            }
        }
        c[(4, idx::PSI)] = 1.0;
        c[(5, idx::P)] = 1.0;
        c[(6, idx::Q)] = 1.0;
        c[(7, idx::R)] = 1.0;
        Linearization {
            a,
            b,
            c,
            x0: *x,
            u0: *u,
        }
    }
}

/// Sines and cosines of `[phi, theta, psi, alpha]`.
#[derive(Clone, Copy)]
struct Trig {
    s: [f64; 4],
    c: [f64; 4],
}

const TRIG_IDX: [usize; 4] = [idx::PHI, idx::THETA, idx::PSI, idx::ALPHA];

impl Trig {
    #[inline]
    fn of(x: &State) -> Self {
        let mut t = Trig {
            s: [0.0; 4],
            c: [0.0; 4],
        };
        for (k, &i) in TRIG_IDX.iter().enumerate() {
            (t.s[k], t.c[k]) = x[i].sin_cos();
        }
        t
    }
}

/// The corrected (3.3): `Q = Qx(phi) Qy(theta) Qz(psi)`, world to body.
#[inline]
fn rotation(sf: f64, cf: f64, st: f64, ct: f64, ss: f64, cs: f64) -> [[f64; 3]; 3] {
    [
        [ct * cs, ct * ss, -st],
        [sf * st * cs - cf * ss, sf * st * ss + cf * cs, sf * ct],
        [cf * st * cs + sf * ss, cf * st * ss - sf * cs, cf * ct],
    ]
}

/// `[dQ/dphi, dQ/dtheta, dQ/dpsi]`.
fn rotation_partials(sf: f64, cf: f64, st: f64, ct: f64, ss: f64, cs: f64) -> [[[f64; 3]; 3]; 3] {
    [
        [
            [0.0, 0.0, 0.0],
            [cf * st * cs + sf * ss, cf * st * ss - sf * cs, cf * ct],
            [-sf * st * cs + cf * ss, -sf * st * ss - cf * cs, -sf * ct],
        ],
        [
            [-st * cs, -st * ss, -ct],
            [sf * ct * cs, sf * ct * ss, -sf * st],
            [cf * ct * cs, cf * ct * ss, -cf * st],
        ],
        [
            [-ct * ss, ct * cs, 0.0],
            [-sf * st * ss - cf * cs, sf * st * cs - cf * ss, 0.0],
            [-cf * st * ss + sf * cs, cf * st * cs + sf * ss, 0.0],
        ],
    ]
}

/// The world-to-body rotation `Q` of (3.3, corrected) for Euler angles
/// `(phi, theta, psi)`; its transpose maps body vectors to the world frame.
pub fn rotation_matrix(phi: f64, theta: f64, psi: f64) -> [[f64; 3]; 3] {
    let (sf, cf) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    let (ss, cs) = psi.sin_cos();
    rotation(sf, cf, st, ct, ss, cs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    fn model() -> Tricopter {
        Tricopter::new(Params::default()).unwrap()
    }

    fn random_point(rng: &mut Xoshiro256PlusPlus) -> (State, Input) {
        let mut x = [0.0; NX];
        let mut r = |lo: f64, hi: f64| rng.random_range(lo..hi);
        for i in 0..3 {
            x[idx::X + i] = r(-200.0, 200.0);
            x[idx::VX + i] = r(-5.0, 5.0);
            x[idx::PHI + i] = r(-0.7, 0.7);
            x[idx::P + i] = r(-2.0, 2.0);
            x[idx::W1 + i] = r(150.0, 900.0);
        }
        x[idx::PSI] = r(-3.0, 3.0);
        x[idx::ALPHA] = r(-0.5, 0.5);
        x[idx::ALPHA_DOT] = r(-2.0, 2.0);
        let u = [
            r(1050.0, 1950.0),
            r(1050.0, 1950.0),
            r(1050.0, 1950.0),
            r(1250.0, 1750.0),
        ];
        (x, u)
    }

    fn close(an: f64, fd: f64, scale: f64) -> bool {
        (an - fd).abs() <= 1e-6 * (an.abs().max(1e-3 * scale)) + 1e-12
    }

    #[test]
    fn jacobians_match_central_differences() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        for models in [Params::default(), Params::thesis_table_7_1()] {
            let m = Tricopter::new(models).unwrap();
            for _ in 0..25 {
                let (x, u) = random_point(&mut rng);
                let lin = m.linearize(&x, &u);
                let fd_a = SMatrix::<f64, NX, NX>::from_fn(|i, j| {
                    let h = if j < 3 {
                        1.0
                    } else {
                        1e-5 * (1.0 + x[j].abs())
                    };
                    let (mut xp, mut xm) = (x, x);
                    xp[j] += h;
                    xm[j] -= h;
                    (m.derivative(&xp, &u)[i] - m.derivative(&xm, &u)[i]) / (2.0 * h)
                });
                let fd_b = SMatrix::<f64, NX, NU>::from_fn(|i, j| {
                    let h = 1e-3;
                    let (mut up, mut um) = (u, u);
                    up[j] += h;
                    um[j] -= h;
                    (m.derivative(&x, &up)[i] - m.derivative(&x, &um)[i]) / (2.0 * h)
                });
                let fd_c = SMatrix::<f64, NY, NX>::from_fn(|i, j| {
                    let h = if j < 3 {
                        1.0
                    } else {
                        1e-5 * (1.0 + x[j].abs())
                    };
                    let (mut xp, mut xm) = (x, x);
                    xp[j] += h;
                    xm[j] -= h;
                    (m.output(&xp)[i] - m.output(&xm)[i]) / (2.0 * h)
                });
                for i in 0..NX {
                    let sa = lin.a.row(i).amax();
                    let sb = lin.b.row(i).amax();
                    for j in 0..NX {
                        assert!(
                            close(lin.a[(i, j)], fd_a[(i, j)], sa),
                            "A[{i}][{j}] = {} vs fd {}",
                            lin.a[(i, j)],
                            fd_a[(i, j)]
                        );
                    }
                    for j in 0..NU {
                        assert!(
                            close(lin.b[(i, j)], fd_b[(i, j)], sb),
                            "B[{i}][{j}] = {} vs fd {}",
                            lin.b[(i, j)],
                            fd_b[(i, j)]
                        );
                    }
                }
                for i in 0..NY {
                    let sc = lin.c.row(i).amax();
                    for j in 0..NX {
                        assert!(
                            close(lin.c[(i, j)], fd_c[(i, j)], sc),
                            "C[{i}][{j}] = {} vs fd {}",
                            lin.c[(i, j)],
                            fd_c[(i, j)]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn rk4_converges_at_fourth_order() {
        // Independent of the trig shortcut: halving dt must cut the error of
        // a 1 s manoeuvre by about 16 (reference: dt = 1e-4).
        let m = model();
        let trim = m.trim_hover().unwrap();
        let u = [1600.0, 1450.0, 1500.0, 1300.0];
        let run = |dt: f64| {
            let mut x = trim.state;
            for _ in 0..(1.0 / dt).round() as usize {
                m.step(&mut x, &u, dt).unwrap();
            }
            x
        };
        let reference = run(1e-4);
        let err = |x: State| {
            (0..NX)
                .map(|i| (x[i] - reference[i]).abs())
                .fold(0.0, f64::max)
        };
        let (e1, e2) = (err(run(4e-3)), err(run(2e-3)));
        let ratio = e1 / e2;
        assert!(ratio > 12.0 && ratio < 20.0, "{e1} {e2} {ratio}");
    }

    #[test]
    fn rotation_is_orthonormal_and_matches_factor_product() {
        let (f, t, s) = (0.3, -0.4, 1.1);
        let q = rotation_matrix(f, t, s);
        // Independent: the product of the three factor matrices of (3.3).
        let qx =
            nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, f.cos(), f.sin(), 0.0, -f.sin(), f.cos());
        let qy =
            nalgebra::Matrix3::new(t.cos(), 0.0, -t.sin(), 0.0, 1.0, 0.0, t.sin(), 0.0, t.cos());
        let qz =
            nalgebra::Matrix3::new(s.cos(), s.sin(), 0.0, -s.sin(), s.cos(), 0.0, 0.0, 0.0, 1.0);
        let want = qx * qy * qz;
        for i in 0..3 {
            for j in 0..3 {
                assert!((q[i][j] - want[(i, j)]).abs() < 1e-15);
            }
        }
        let qm = nalgebra::Matrix3::from_fn(|i, j| q[i][j]);
        assert!((qm * qm.transpose() - nalgebra::Matrix3::identity()).amax() < 1e-15);
    }

    #[test]
    fn free_fall_conserves_energy_and_horizontal_momentum() {
        let m = model();
        let mut x = [0.0; NX];
        x[idx::Z] = -500.0;
        x[idx::VX] = 3.0;
        x[idx::VY] = -2.0;
        x[idx::VZ] = -4.0;
        x[idx::PHI] = 0.2;
        x[idx::P] = 0.5;
        let u = [1000.0, 1000.0, 1000.0, 1500.0];
        let g = m.params().gravity;
        let energy = |x: &State| 0.5 * (x[3] * x[3] + x[4] * x[4] + x[5] * x[5]) - g * x[idx::Z];
        let e0 = energy(&x);
        for _ in 0..5000 {
            m.step(&mut x, &u, 1e-3).unwrap();
        }
        assert!(
            (energy(&x) - e0).abs() < 1e-9 * e0.abs(),
            "{} vs {e0}",
            energy(&x)
        );
        assert!((x[idx::VX] - 3.0).abs() < 1e-12 && (x[idx::VY] + 2.0).abs() < 1e-12);
        // Closed form of the fall: z(t) = z0 + w0 t + g t^2 / 2.
        let t = 5.0;
        assert!((x[idx::Z] - (-500.0 - 4.0 * t + 0.5 * g * t * t)).abs() < 1e-8);
    }

    #[test]
    fn torque_free_spin_conserves_angular_momentum() {
        let m = model();
        let p = *m.params();
        let mut x = [0.0; NX];
        x[idx::P] = 0.3;
        x[idx::Q] = -0.2;
        x[idx::R] = 3.0;
        x[idx::PHI] = 0.1;
        let u = [1000.0, 1000.0, 1000.0, 1500.0];
        let moments = |x: &State| {
            let h = [p.ixx * x[idx::P], p.iyy * x[idx::Q], p.izz * x[idx::R]];
            let q = rotation_matrix(x[idx::PHI], x[idx::THETA], x[idx::PSI]);
            // World frame: Q^T h.
            let hw: [f64; 3] =
                core::array::from_fn(|i| q[0][i] * h[0] + q[1][i] * h[1] + q[2][i] * h[2]);
            let e = 0.5 * (h[0] * x[idx::P] + h[1] * x[idx::Q] + h[2] * x[idx::R]);
            (hw, e)
        };
        let (h0, e0) = moments(&x);
        for _ in 0..5000 {
            m.step(&mut x, &u, 1e-3).unwrap();
        }
        let (h1, e1) = moments(&x);
        for i in 0..3 {
            assert!((h1[i] - h0[i]).abs() < 1e-8, "{h0:?} -> {h1:?}");
        }
        assert!((e1 - e0).abs() < 1e-9 * e0);
        // The rates really changed (the test is not trivially static).
        assert!((x[idx::P] - 0.3).abs() > 1e-3);
    }

    #[test]
    fn bad_input_is_an_error() {
        let m = model();
        let mut x = [0.0; NX];
        let before = x;
        assert!(matches!(
            m.step(&mut x, &[f64::NAN, 1500.0, 1500.0, 1500.0], 1e-3),
            Err(ModelError::NonFinite { what: "input" })
        ));
        assert!(matches!(
            m.step(&mut x, &[1500.0; 4], -1.0),
            Err(ModelError::InvalidSetting { name: "dt", .. })
        ));
        x[idx::P] = f64::INFINITY;
        assert!(matches!(
            m.step(&mut x, &[1500.0; 4], 1e-3),
            Err(ModelError::NonFinite { what: "state" })
        ));
        assert_eq!(before[idx::Z], x[idx::Z]);
        assert!(
            Tricopter::new(Params {
                mass: -1.0,
                ..Params::default()
            })
            .is_err()
        );
        assert!(
            Tricopter::new(Params {
                ixx: f64::NAN,
                ..Params::default()
            })
            .is_err()
        );
    }

    #[test]
    fn inputs_saturate() {
        let m = model();
        let x = [0.0; NX];
        let hi = m.derivative(&x, &[2500.0, 2000.0, 900.0, 1900.0]);
        let edge = m.derivative(&x, &[2000.0, 2000.0, 1000.0, 1800.0]);
        assert_eq!(hi, edge);
    }

    #[test]
    fn ground_contact_holds_a_resting_aircraft() {
        let m = model();
        let mut x = [0.0; NX];
        let u = [1000.0, 1000.0, 1000.0, 1500.0];
        for _ in 0..100 {
            m.step(&mut x, &u, 1e-3).unwrap();
            assert!(m.apply_ground(&mut x));
        }
        assert_eq!(x[idx::Z], 0.0);
        assert_eq!(x[idx::VZ], 0.0);
    }
}
