//! Hover trim: the inputs (and the small roll angle) that hold the aircraft still.

use crate::error::ModelError;
use crate::model::{Input, NX, State, Tricopter, idx};
use nalgebra::{SMatrix, SVector};
use std::fmt;

/// The hover operating point, reported like (7.2).
#[derive(Clone, Debug, PartialEq)]
pub struct Trim {
    /// The equilibrium state (at the origin, heading 0, zero velocity and rates).
    pub state: State,
    /// The equilibrium input `[pwm1, pwm2, pwm3, servo]` (us).
    pub input: Input,
    /// Rotor speeds (rad/s).
    pub omega: [f64; 3],
    /// Servo tilt `alpha_0` (rad).
    pub alpha: f64,
    /// Roll angle at hover (rad): small and non-zero because the tilted rear
    /// rotor pushes sideways, which the aircraft must lean against.
    pub phi: f64,
    /// Pitch angle at hover (rad).
    pub theta: f64,
    /// Common throttle: the mean of the three ESC pulses (us).
    pub throttle: f64,
    /// `U_0` of (7.2): `[pwm1 - throttle, pwm2 - throttle, pwm3 - throttle, servo]` (us).
    pub offsets: [f64; 4],
    /// `max |f(x0, u0)|` over all states: the trim residual.
    pub residual: f64,
    /// Newton iterations used.
    pub iterations: usize,
}

impl fmt::Display for Trim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let o = self.offsets;
        write!(
            f,
            "U_0 = [{:.2}, {:.2}, {:.2}, {:.1}] us at throttle {:.1} us; alpha_0 = {:.3} deg, \
             phi_0 = {:.3} deg, theta_0 = {:.3} deg; residual {:.1e}",
            o[0],
            o[1],
            o[2],
            o[3],
            self.throttle,
            self.alpha.to_degrees(),
            self.phi.to_degrees(),
            self.theta.to_degrees(),
            self.residual
        )
    }
}

impl Tricopter {
    /// Solves for hover at heading 0: the three rotor speeds, the servo tilt
    /// that cancels the net rotor reaction torque, and the roll and pitch
    /// angles at which the forces balance (Newton's method on the six force
    /// and moment equations with the analytic Jacobian), to a residual below
    /// 1e-9 in every state derivative.
    ///
    /// Errors with [`ModelError::TrimNotConverged`] when the parameters
    /// cannot hover (e.g. Table 7.1, whose reaction torque no tilt can
    /// cancel), and [`ModelError::InvalidSetting`] when the trim needs pulses
    /// outside their ranges.
    pub fn trim_hover(&self) -> Result<Trim, ModelError> {
        let p = *self.params();
        let w0 = (p.mass * p.gravity / (3.0 * p.k_t)).sqrt();
        // Unknowns z = [w1, w2, w3, alpha, phi, theta].
        let mut z = SVector::<f64, 6>::from([w0, w0, w0, 0.0, 0.0, 0.0]);
        let rows = [idx::VX, idx::VY, idx::VZ, idx::P, idx::Q, idx::R];
        let cols = [idx::W1, idx::W2, idx::W3, idx::ALPHA, idx::PHI, idx::THETA];
        let build = |z: &SVector<f64, 6>| -> (State, Input) {
            let mut x = [0.0; NX];
            for (k, &c) in cols.iter().enumerate() {
                x[c] = z[k];
            }
            let u = [
                p.pwm_for_rotor_speed(z[0]),
                p.pwm_for_rotor_speed(z[1]),
                p.pwm_for_rotor_speed(z[2]),
                p.servo_pwm_for_tilt(z[3]),
            ];
            (x, u)
        };
        let max_iter = 50;
        let mut residual = f64::INFINITY;
        let mut iterations = 0;
        for it in 0..max_iter {
            let (x, u) = build(&z);
            let dx = self.derivative(&x, &u);
            let r = SVector::<f64, 6>::from_fn(|i, _| dx[rows[i]]);
            residual = r.amax();
            iterations = it;
            if residual < 1e-12 {
                break;
            }
            let lin = self.linearize(&x, &u);
            let j = SMatrix::<f64, 6, 6>::from_fn(|i, k| lin.a[(rows[i], cols[k])]);
            let Some(step) = j.lu().solve(&r) else {
                break;
            };
            // Damped step: keep the tilt and angles inside +-60 degrees.
            let mut s = 1.0;
            while s > 1e-3 {
                let cand = z - step * s;
                if cand[3].abs() < 1.05 && cand[4].abs() < 1.05 && cand[5].abs() < 1.05 {
                    break;
                }
                s *= 0.5;
            }
            z -= step * s;
            if !z.iter().all(|v| v.is_finite()) {
                break;
            }
        }
        let (x, u) = build(&z);
        let dx = self.derivative(&x, &u);
        let full = dx.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        if !(full.is_finite() && full < 1e-9) {
            return Err(ModelError::TrimNotConverged {
                residual: if full.is_finite() { full } else { residual },
                iterations: iterations + 1,
            });
        }
        for (i, &v) in u.iter().enumerate() {
            let (lo, hi) = if i < 3 {
                (1000.0, 2000.0)
            } else {
                (1200.0, 1800.0)
            };
            if !(v > lo && v < hi) {
                return Err(ModelError::InvalidSetting {
                    name: "trim",
                    reason: format!(
                        "hover needs pulse {} = {v:.1} us, outside [{lo}, {hi}]",
                        crate::model::INPUT_NAMES[i]
                    ),
                });
            }
        }
        let throttle = (u[0] + u[1] + u[2]) / 3.0;
        Ok(Trim {
            state: x,
            input: u,
            omega: [z[0], z[1], z[2]],
            alpha: z[3],
            phi: z[4],
            theta: z[5],
            throttle,
            offsets: [u[0] - throttle, u[1] - throttle, u[2] - throttle, u[3]],
            residual: full,
            iterations: iterations + 1,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;

    #[test]
    fn hover_trim_residual_below_1e_9() {
        let m = Tricopter::new(Params::default()).unwrap();
        let t = m.trim_hover().unwrap();
        assert!(t.residual < 1e-9, "{t}");
        // Independent check of the residual with the full derivative.
        let dx = m.derivative(&t.state, &t.input);
        assert!(dx.iter().all(|v| v.abs() < 1e-9));
        // Roughly half throttle, a small tilt, a small roll.
        assert!((t.throttle - 1500.0).abs() < 100.0, "{t}");
        assert!(t.alpha.abs() < 0.2 && t.alpha.abs() > 0.01);
        assert!(t.phi.abs() < 0.05);
        // Vertical balance: sum of vertical thrust equals weight (closed form check).
        let p = m.params();
        let f: Vec<f64> = t.omega.iter().map(|w| p.k_t * w * w).collect();
        let vertical = (f[0] * t.alpha.cos() + f[1] + f[2]) * t.phi.cos() * t.theta.cos()
            - f[0] * t.alpha.sin() * t.phi.sin() * t.theta.cos();
        assert!((vertical - p.mass * p.gravity).abs() < 1e-9);
        // Yaw balance: the tilt cancels the rear rotor's reaction torque.
        let yaw = -p.arm_length * f[0] * t.alpha.sin()
            - p.k_tau
                * (p.spin[0] * t.omega[0].powi(2) * t.alpha.cos()
                    + p.spin[1] * t.omega[1].powi(2)
                    + p.spin[2] * t.omega[2].powi(2));
        assert!(yaw.abs() < 1e-9);
        let s = t.to_string();
        assert!(s.starts_with("U_0 = ["));
    }

    #[test]
    fn table_7_1_cannot_hover() {
        let m = Tricopter::new(Params::thesis_table_7_1()).unwrap();
        assert!(matches!(
            m.trim_hover(),
            Err(ModelError::TrimNotConverged { .. })
        ));
    }
}
