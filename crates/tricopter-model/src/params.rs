//! Physical parameters of the tricopter, validated on construction.

use crate::error::ModelError;

/// Physical parameters of the tricopter (SI units unless stated).
///
/// Geometry (body frame Front-Right-Down, centre of mass at the origin):
/// rotor 1 (tilting, rear) at `(-l, 0, 0)`, rotor 2 (front left) at
/// `(l/2, -sqrt(3)/2 l, 0)`, rotor 3 (front right) at `(l/2, sqrt(3)/2 l, 0)`,
/// i.e. arms of length `l` at 120 degrees (thesis figure 3.4).
///
/// Rotors: thrust `f_i = k_t w_i |w_i|` along the rotor axis (3.4a); reaction
/// torque `spin_i k_tau w_i |w_i|` along the same axis (3.4b), where
/// `spin_i = +1` is the sign convention of (3.14b). Motors: first order,
/// `tau_m w_i' = w_ss(pwm_i) - w_i` with `w_ss = omega_max (pwm - 1000)/1000`
/// (3.9 with the PWM map). Servo: second order,
/// `alpha'' = wn^2 (alpha_cmd - alpha) - 2 zeta wn alpha'` with
/// `alpha_cmd = servo_gain (pwm_s - servo_center)`.
///
/// ```
/// use kestrel_tricopter_model::Params;
/// let p = Params::default().validated().unwrap();
/// assert_eq!(p.arm_length, 0.5);
/// let bad = Params { mass: -1.0, ..Params::default() };
/// assert!(bad.validated().unwrap_err().to_string().contains("mass"));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// Mass `m` (kg).
    pub mass: f64,
    /// Gravitational acceleration `g` (m/s^2).
    pub gravity: f64,
    /// Arm length `l` (m), centre of mass to each rotor hub.
    pub arm_length: f64,
    /// Moment of inertia about the body x axis `I_xx` (kg m^2).
    pub ixx: f64,
    /// Moment of inertia about the body y axis `I_yy` (kg m^2).
    pub iyy: f64,
    /// Moment of inertia about the body z axis `I_zz` (kg m^2).
    pub izz: f64,
    /// Thrust constant `k_t` (N s^2/rad^2).
    pub k_t: f64,
    /// Drag (reaction torque) constant `k_tau` (N m s^2/rad^2).
    pub k_tau: f64,
    /// Spin sign of each rotor's reaction torque (`+1` or `-1`), see the type docs.
    pub spin: [f64; 3],
    /// Motor time constant `tau_m` (s).
    pub motor_tau: f64,
    /// Rotor speed at 2000 us (rad/s); the ESC map is linear from 0 at 1000 us.
    pub omega_max: f64,
    /// Servo natural frequency `wn` (rad/s).
    pub servo_wn: f64,
    /// Servo damping ratio `zeta` (-).
    pub servo_zeta: f64,
    /// Servo gain (rad/us); its sign is the servo direction (negative = reversed).
    pub servo_gain: f64,
    /// Servo pulse at zero tilt (us).
    pub servo_center: f64,
    /// Latitude of the world origin (degrees), for the GPS outputs of (3.22).
    pub origin_lat_deg: f64,
    /// Longitude of the world origin (degrees).
    pub origin_lng_deg: f64,
}

/// Earth radius used by (3.2) (m).
pub const R_EARTH: f64 = 6_371_000.0;

impl Default for Params {
    /// A physically consistent 1.1 kg tricopter with 0.5 m arms.
    ///
    /// Hover needs about 3.6 N per rotor, i.e. `w ~ 490 rad/s` with
    /// `k_t = 1.5e-5`, about 1490 us: roughly half throttle. Inertias are those of
    /// three 0.1 kg motors at the arm tips plus a 0.8 kg central body
    /// (`I_zz <= I_xx + I_yy` holds). `k_tau/k_t = 0.02 m` is typical of a 10"
    /// propeller. All three rotors spin the same way, as in (3.14b) (here
    /// `spin = [-1, -1, -1]`, i.e. the other way round than the thesis's
    /// sign, which puts the hover servo pulse below centre like (7.2)): the
    /// odd rotor count leaves a net reaction torque that the rear tilt (about
    /// 7 degrees) cancels, and the reduced rate models have the zero pattern
    /// of (7.7) and (C.1). (With a counter-rotating front pair, the tilt
    /// cancels the rear rotor alone and `dq'/dalpha`, `dr'/dw1` vanish at
    /// trim.) The servo is reversed (`servo_gain < 0`) so that a positive
    /// virtual yaw input gives a positive yaw moment.
    fn default() -> Self {
        Params {
            mass: 1.1,
            gravity: 9.81,
            arm_length: 0.5,
            ixx: 0.040,
            iyy: 0.045,
            izz: 0.080,
            k_t: 1.5e-5,
            k_tau: 3.0e-7,
            spin: [-1.0, -1.0, -1.0],
            motor_tau: 0.05,
            omega_max: 1000.0,
            servo_wn: 30.0,
            servo_zeta: 0.7,
            servo_gain: -40.0_f64.to_radians() / 300.0,
            servo_center: 1500.0,
            origin_lat_deg: 58.3977,
            origin_lng_deg: 15.5760,
        }
    }
}

impl Params {
    /// The thesis's Table 7.1 (from another aircraft, Yoo et al. 2010): the
    /// grey-box initial guess. Not self-consistent (see `ERRATA.md`): with
    /// `k_t = 2^-6` and `w_0 = 2 pi 50 rad/s` each rotor would lift ~1500 N.
    /// The table gives no mass, motor or servo data; those are taken from
    /// [`Params::default`], `omega_max` is set so that `w_0 = 2 pi 50` is half
    /// throttle and all rotors spin the same way as in (3.14b).
    pub fn thesis_table_7_1() -> Self {
        Params {
            ixx: 0.2,
            iyy: 0.1,
            izz: 0.1,
            k_tau: 2f64.powi(-7),
            k_t: 2f64.powi(-6),
            arm_length: 0.5,
            spin: [1.0, 1.0, 1.0],
            omega_max: 2.0 * 2.0 * std::f64::consts::PI * 50.0,
            ..Params::default()
        }
    }

    /// Checks every parameter, returning the parameters or an error that
    /// names the first offending one.
    pub fn validated(self) -> Result<Self, ModelError> {
        self.validate()?;
        Ok(self)
    }

    /// Checks every parameter (finite, positive where physical, spins `+-1`,
    /// inertia triangle inequalities).
    pub fn validate(&self) -> Result<(), ModelError> {
        let positive = [
            ("mass", self.mass),
            ("gravity", self.gravity),
            ("arm_length", self.arm_length),
            ("ixx", self.ixx),
            ("iyy", self.iyy),
            ("izz", self.izz),
            ("k_t", self.k_t),
            ("motor_tau", self.motor_tau),
            ("omega_max", self.omega_max),
            ("servo_wn", self.servo_wn),
            ("servo_zeta", self.servo_zeta),
        ];
        for (name, value) in positive {
            if !value.is_finite() {
                return Err(ModelError::InvalidParam {
                    name,
                    value,
                    reason: "must be finite",
                });
            }
            if value <= 0.0 {
                return Err(ModelError::InvalidParam {
                    name,
                    value,
                    reason: "must be positive",
                });
            }
        }
        let finite = [
            ("k_tau", self.k_tau),
            ("servo_gain", self.servo_gain),
            ("servo_center", self.servo_center),
            ("origin_lat_deg", self.origin_lat_deg),
            ("origin_lng_deg", self.origin_lng_deg),
        ];
        for (name, value) in finite {
            if !value.is_finite() {
                return Err(ModelError::InvalidParam {
                    name,
                    value,
                    reason: "must be finite",
                });
            }
        }
        if self.k_tau < 0.0 {
            return Err(ModelError::InvalidParam {
                name: "k_tau",
                value: self.k_tau,
                reason: "must be non-negative",
            });
        }
        if self.servo_gain == 0.0 {
            return Err(ModelError::InvalidParam {
                name: "servo_gain",
                value: 0.0,
                reason: "must be non-zero",
            });
        }
        if self.origin_lat_deg.abs() >= 89.0 {
            return Err(ModelError::InvalidParam {
                name: "origin_lat_deg",
                value: self.origin_lat_deg,
                reason: "must be within +-89 degrees",
            });
        }
        for s in self.spin {
            if s != 1.0 && s != -1.0 {
                return Err(ModelError::InvalidParam {
                    name: "spin",
                    value: s,
                    reason: "each entry must be +1 or -1",
                });
            }
        }
        let (a, b, c) = (self.ixx, self.iyy, self.izz);
        let slack = 1e-12 * (a + b + c);
        for (name, value, rest) in [("ixx", a, b + c), ("iyy", b, a + c), ("izz", c, a + b)] {
            if value > rest + slack {
                return Err(ModelError::InvalidParam {
                    name,
                    value,
                    reason: "violates the inertia triangle inequality (each principal moment <= sum of the other two)",
                });
            }
        }
        Ok(())
    }

    /// Steady-state rotor speed for an ESC pulse (rad/s), the pulse saturated.
    #[inline]
    pub fn rotor_speed_for_pwm(&self, pwm: f64) -> f64 {
        self.omega_max * (pwm.clamp(1000.0, 2000.0) - 1000.0) * 1e-3
    }

    /// ESC pulse that gives rotor speed `omega` in steady state (unsaturated).
    #[inline]
    pub fn pwm_for_rotor_speed(&self, omega: f64) -> f64 {
        1000.0 + omega / self.omega_max * 1e3
    }

    /// Commanded tilt for a servo pulse (rad), the pulse saturated.
    #[inline]
    pub fn tilt_for_servo_pwm(&self, pwm: f64) -> f64 {
        self.servo_gain * (pwm.clamp(1200.0, 1800.0) - self.servo_center)
    }

    /// Servo pulse for tilt `alpha` (unsaturated).
    #[inline]
    pub fn servo_pwm_for_tilt(&self, alpha: f64) -> f64 {
        self.servo_center + alpha / self.servo_gain
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_and_table_are_valid() {
        Params::default().validate().unwrap();
        Params::thesis_table_7_1().validate().unwrap();
    }

    #[test]
    fn bad_values_are_named() {
        let cases: [(Params, &str); 8] = [
            (
                Params {
                    mass: -1.0,
                    ..Default::default()
                },
                "mass",
            ),
            (
                Params {
                    ixx: f64::NAN,
                    ..Default::default()
                },
                "ixx",
            ),
            (
                Params {
                    k_t: 0.0,
                    ..Default::default()
                },
                "k_t",
            ),
            (
                Params {
                    k_tau: f64::INFINITY,
                    ..Default::default()
                },
                "k_tau",
            ),
            (
                Params {
                    spin: [1.0, 0.5, 1.0],
                    ..Default::default()
                },
                "spin",
            ),
            (
                Params {
                    izz: 1.0,
                    ..Default::default()
                },
                "izz",
            ),
            (
                Params {
                    servo_gain: 0.0,
                    ..Default::default()
                },
                "servo_gain",
            ),
            (
                Params {
                    motor_tau: -0.1,
                    ..Default::default()
                },
                "motor_tau",
            ),
        ];
        for (p, name) in cases {
            let e = p.validate().unwrap_err();
            assert!(
                matches!(e, ModelError::InvalidParam { name: n, .. } if n == name),
                "{e}"
            );
            assert!(e.to_string().contains(name));
        }
    }

    #[test]
    fn pwm_maps_invert_and_saturate() {
        let p = Params::default();
        let w = p.rotor_speed_for_pwm(1500.0);
        assert!((p.pwm_for_rotor_speed(w) - 1500.0).abs() < 1e-9);
        assert_eq!(p.rotor_speed_for_pwm(900.0), 0.0);
        assert_eq!(p.rotor_speed_for_pwm(2100.0), p.omega_max);
        let a = p.tilt_for_servo_pwm(1600.0);
        assert!((p.servo_pwm_for_tilt(a) - 1600.0).abs() < 1e-9);
        assert_eq!(p.tilt_for_servo_pwm(1900.0), p.tilt_for_servo_pwm(1800.0));
    }
}
