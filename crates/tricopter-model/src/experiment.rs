//! The thesis's four experiments (section 7.1) as seeded generators of CSV
//! flight logs.
//!
//! A simulated pilot flies the aircraft in ACRO mode through the baseline
//! [`RatePid`]: it sets the throttle (altitude hold with a climb and descent
//! ramp), holds the attitude and the position loosely by rate references
//! from the true attitude and velocity (what a pilot sees), and adds the
//! excitation. Timeline for `T = seconds`:
//!
//! | time (s)            | phase |
//! |---------------------|-------|
//! | 0 - 2               | on the ground, motors stopped |
//! | 2 - ~5              | take-off: climb at 0.5 m/s to 1.5 m |
//! | 10 - T-5            | excitation (experiments 2 and 3) |
//! | T-3.5 - ~T-1.5      | landing: descent at 0.75 m/s, throttle cut on touchdown |
//!
//! so with `T = 250` the thesis's estimation and validation intervals
//! (e.g. 25.66-50.28 s and 108.9-165.8 s) are excited flight; the last one,
//! 227.28-249.84 s of flight 3, ends in the landing.
//!
//! - [`Experiment::Hover`] (no. 1): hover, no excitation.
//! - [`Experiment::Decoupled`] (no. 2): random multi-level rate references
//!   on one axis at a time, 6 s each (roll, pitch, yaw, ...), 2 s rest between.
//! - [`Experiment::Coupled`] (no. 3): the same signals on all axes together.
//! - [`Experiment::Ground`] (no. 4): motors off on the ground (gyro bias and
//!   noise only).

use crate::error::ModelError;
use crate::mixer::Mixer;
use crate::model::{State, idx};
use crate::pid::{RatePid, RatePidGains};
use crate::plant::{Plant, PlantConfig};
use crate::sensor::{GustConfig, GyroConfig};
use crate::trim::Trim;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::str::FromStr;

/// The four experiments of section 7.1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Experiment {
    /// No. 1: hovering.
    Hover,
    /// No. 2: decoupled excitation, one axis at a time.
    Decoupled,
    /// No. 3: coupled excitation, all axes together.
    Coupled,
    /// No. 4 (section 7.1.4): motors off on the ground.
    Ground,
}

impl Experiment {
    /// All experiments in thesis order.
    pub const ALL: [Experiment; 4] = [
        Experiment::Hover,
        Experiment::Decoupled,
        Experiment::Coupled,
        Experiment::Ground,
    ];

    /// The name used on the command line (`hover`, `decoupled`, `coupled`, `ground`).
    pub fn name(self) -> &'static str {
        match self {
            Experiment::Hover => "hover",
            Experiment::Decoupled => "decoupled",
            Experiment::Coupled => "coupled",
            Experiment::Ground => "ground",
        }
    }

    /// The thesis's number of the experiment (1-4).
    pub fn number(self) -> u8 {
        match self {
            Experiment::Hover => 1,
            Experiment::Decoupled => 2,
            Experiment::Coupled => 3,
            Experiment::Ground => 4,
        }
    }
}

impl FromStr for Experiment {
    type Err = ModelError;
    /// Parses a name of [`Experiment::name`]; anything else is an error
    /// listing the valid names.
    fn from_str(s: &str) -> Result<Self, ModelError> {
        Experiment::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| ModelError::InvalidSetting {
                name: "experiment",
                reason: format!(
                    "unknown experiment {s:?} (expected one of hover, decoupled, coupled, ground)"
                ),
            })
    }
}

/// Settings of a simulated experiment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSettings {
    /// Which experiment.
    pub experiment: Experiment,
    /// Length of the log (s).
    pub seconds: f64,
    /// Random seed (gyro noise, gusts, excitation).
    pub seed: u64,
    /// The plant: aircraft, gyro (its rate is the log and control rate),
    /// gusts, integration step.
    pub plant: PlantConfig,
    /// Rate controller gains (their `dt` is replaced by the sample period).
    pub gains: RatePidGains<f64>,
    /// Excitation amplitude per axis (rad/s).
    pub excitation: [f64; 3],
    /// Hover altitude (m).
    pub hover_altitude: f64,
}

impl SimSettings {
    /// The defaults for an experiment: default aircraft, thesis gyro,
    /// light gusts, 1 kHz RK4, 50 Hz control and log, excitation 1 rad/s.
    pub fn new(experiment: Experiment, seconds: f64, seed: u64) -> Self {
        SimSettings {
            experiment,
            seconds,
            seed,
            plant: PlantConfig::default(),
            gains: RatePidGains::default(),
            excitation: [1.0, 1.0, 1.0],
            hover_altitude: 1.5,
        }
    }

    /// Without noise, bias, quantisation and gusts (for tests of the dynamics).
    pub fn noiseless(mut self) -> Self {
        self.plant.gyro = GyroConfig::ideal();
        self.plant.gust = GustConfig::calm();
        self
    }
}

/// One 50 Hz log sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRow {
    /// Time (s).
    pub t: f64,
    /// `[pwm1, pwm2, pwm3, servo]` applied from this sample on (us).
    pub pwm: [f64; 4],
    /// Pilot throttle (us).
    pub throttle: f64,
    /// Mixer virtual inputs `[U_r, U_p, U_y]` (us).
    pub virtual_input: [f64; 3],
    /// Gyro measurement `[p, q, r]` (rad/s).
    pub gyro: [f64; 3],
    /// Rate references (rad/s).
    pub reference: [f64; 3],
    /// True state at this sample.
    pub state: State,
    /// Whether the aircraft is off the ground.
    pub airborne: bool,
}

/// The column names of the CSV log, in order (see the crate README).
pub const LOG_COLUMNS: [&str; 32] = [
    "t",
    "pwm1",
    "pwm2",
    "pwm3",
    "servo",
    "throttle",
    "u_roll",
    "u_pitch",
    "u_yaw",
    "p",
    "q",
    "r",
    "ref_p",
    "ref_q",
    "ref_r",
    "true_p",
    "true_q",
    "true_r",
    "true_phi",
    "true_theta",
    "true_psi",
    "true_x",
    "true_y",
    "true_z",
    "true_vx",
    "true_vy",
    "true_vz",
    "true_omega1",
    "true_omega2",
    "true_omega3",
    "true_alpha",
    "airborne",
];

impl LogRow {
    /// The row's values in [`LOG_COLUMNS`] order.
    pub fn values(&self) -> [f64; 32] {
        let x = &self.state;
        [
            (self.t * 1e9).round() / 1e9,
            self.pwm[0],
            self.pwm[1],
            self.pwm[2],
            self.pwm[3],
            self.throttle,
            self.virtual_input[0],
            self.virtual_input[1],
            self.virtual_input[2],
            self.gyro[0],
            self.gyro[1],
            self.gyro[2],
            self.reference[0],
            self.reference[1],
            self.reference[2],
            x[idx::P],
            x[idx::Q],
            x[idx::R],
            x[idx::PHI],
            x[idx::THETA],
            x[idx::PSI],
            x[idx::X],
            x[idx::Y],
            x[idx::Z],
            x[idx::VX],
            x[idx::VY],
            x[idx::VZ],
            x[idx::W1],
            x[idx::W2],
            x[idx::W3],
            x[idx::ALPHA],
            if self.airborne { 1.0 } else { 0.0 },
        ]
    }
}

/// A simulated flight: settings, the hover trim of the aircraft and the log.
#[derive(Clone, Debug)]
pub struct FlightLog {
    /// The settings it was made with.
    pub settings: SimSettings,
    /// Hover trim of the aircraft (the true `U_0`, for comparison with (7.2)).
    pub trim: Trim,
    /// The samples.
    pub rows: Vec<LogRow>,
}

impl FlightLog {
    /// Writes the log as CSV (header [`LOG_COLUMNS`], one row per sample;
    /// numbers in Rust's shortest round-trip form, so equal logs give equal bytes).
    pub fn write_csv<W: std::io::Write>(&self, w: W) -> Result<(), ModelError> {
        let err = |e: csv::Error| ModelError::Csv(e.to_string());
        let mut wr = csv::Writer::from_writer(w);
        wr.write_record(LOG_COLUMNS).map_err(err)?;
        let mut buf = [ryu_free::Buf::default(); 32];
        for row in &self.rows {
            let v = row.values();
            for (b, x) in buf.iter_mut().zip(v.iter()) {
                b.set(*x);
            }
            wr.write_record(buf.iter().map(|b| b.as_bytes()))
                .map_err(err)?;
        }
        wr.flush().map_err(|e| ModelError::Csv(e.to_string()))
    }

    /// The CSV text as bytes.
    pub fn to_csv_bytes(&self) -> Result<Vec<u8>, ModelError> {
        let mut out = Vec::with_capacity(self.rows.len() * 400 + 512);
        self.write_csv(&mut out)?;
        Ok(out)
    }

    /// The time intervals `(start, end)` (s) in which the aircraft was airborne.
    pub fn airborne_intervals(&self) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let mut start = None;
        for r in &self.rows {
            match (r.airborne, start) {
                (true, None) => start = Some(r.t),
                (false, Some(s)) => {
                    out.push((s, r.t));
                    start = None;
                }
                _ => {}
            }
        }
        if let (Some(s), Some(last)) = (start, self.rows.last()) {
            out.push((s, last.t));
        }
        out
    }
}

/// Small fixed buffer formatting an `f64` with `Display` without allocating per field.
mod ryu_free {
    use std::io::Write;

    #[derive(Clone, Copy)]
    pub struct Buf {
        data: [u8; 40],
        len: usize,
    }

    impl Default for Buf {
        fn default() -> Self {
            Buf {
                data: [0; 40],
                len: 0,
            }
        }
    }

    impl Buf {
        pub fn set(&mut self, v: f64) {
            let mut cur = std::io::Cursor::new(&mut self.data[..]);
            // `Display` of f64 is the shortest round-trip form; 40 bytes hold
            // every value this log contains (|v| < 1e16 and normal).
            // Tiny magnitudes in exponent form keep the file short; `+ 0.0`
            // turns -0 into 0.
            let v = v + 0.0;
            let ok = if v != 0.0 && v.abs() < 1e-4 {
                write!(cur, "{v:e}").is_ok()
            } else {
                write!(cur, "{v}").is_ok()
            };
            self.len = if ok { cur.position() as usize } else { 0 };
        }
        pub fn as_bytes(&self) -> &[u8] {
            &self.data[..self.len]
        }
    }
}

/// A piecewise-constant random level with random hold times, smoothed like
/// a pilot's stick: a multi-frequency excitation signal.
#[derive(Clone, Debug)]
struct Excitation {
    rng: Xoshiro256PlusPlus,
    target: f64,
    value: f64,
    hold_until: f64,
}

impl Excitation {
    fn new(seed: u64) -> Self {
        Excitation {
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            target: 0.0,
            value: 0.0,
            hold_until: 0.0,
        }
    }

    fn next(&mut self, t: f64, dt: f64, amplitude: f64, active: bool) -> f64 {
        if t >= self.hold_until {
            self.target = amplitude * self.rng.random_range(-1.0..1.0);
            self.hold_until = t + self.rng.random_range(0.15..0.8);
        }
        let target = if active { self.target } else { 0.0 };
        self.value += (target - self.value) * (1.0 - (-dt / 0.05).exp());
        self.value
    }
}

/// The simulated pilot (see the module docs).
struct Pilot {
    settings: SimSettings,
    hover_throttle: f64,
    phi_trim: f64,
    alt_integ: f64,
    excitation: [Excitation; 3],
    cut: bool,
}

const T_TAKEOFF: f64 = 2.0;
const CLIMB_RATE: f64 = 0.5;
const DESCENT_RATE: f64 = 0.75;
const T_EXCITE: f64 = 10.0;

impl Pilot {
    fn landing_start(&self) -> f64 {
        self.settings.seconds - 3.5
    }

    /// Altitude set point and its rate.
    fn altitude_setpoint(&self, t: f64) -> (f64, f64) {
        let h = self.settings.hover_altitude;
        let climb = ((t - T_TAKEOFF) * CLIMB_RATE).clamp(0.0, h);
        let climb_rate = if t > T_TAKEOFF && climb < h {
            CLIMB_RATE
        } else {
            0.0
        };
        let tl = self.landing_start();
        if t > tl {
            let descent = h - (t - tl) * DESCENT_RATE;
            if descent < climb {
                return (descent.max(-0.5), -DESCENT_RATE);
            }
        }
        (climb, climb_rate)
    }

    /// Rate references and throttle for the state `x` at time `t`.
    fn command(&mut self, t: f64, x: &State, airborne: bool) -> ([f64; 3], f64) {
        let s = &self.settings;
        let ts = 1.0 / s.plant.gyro.rate_hz;
        let flying = s.experiment != Experiment::Ground && t >= T_TAKEOFF;
        if t > self.landing_start() && !airborne {
            self.cut = true;
        }
        // Excitation (kept running so that the signals do not depend on the schedule).
        let (active, any) = match s.experiment {
            Experiment::Decoupled => {
                let tau = t - T_EXCITE;
                let seg = (tau / 8.0).floor();
                let on = tau >= 0.0 && tau - seg * 8.0 < 6.0;
                let axis = (seg.max(0.0) as usize) % 3;
                (core::array::from_fn(|i| on && i == axis), true)
            }
            Experiment::Coupled => ([true; 3], true),
            _ => ([false; 3], false),
        };
        let window = any && t >= T_EXCITE && t <= s.seconds - 5.0 && airborne;
        let mut exc = [0.0; 3];
        for i in 0..3 {
            exc[i] = self.excitation[i].next(t, ts, s.excitation[i], window && active[i]);
        }
        if !flying || self.cut {
            self.alt_integ = 0.0;
            return ([0.0; 3], 1000.0);
        }
        // Altitude hold through the throttle (thrust ~ (pwm - 1000)^2).
        let (h_sp, hdot_sp) = self.altitude_setpoint(t);
        let h = -x[idx::Z];
        let hdot = -x[idx::VZ];
        let e = h_sp - h;
        if airborne {
            self.alt_integ = (self.alt_integ + 1.0 * e * ts).clamp(-3.0, 3.0);
        }
        let g = s.plant.params.gravity;
        let a_des = 4.0 * e + 3.6 * (hdot_sp - hdot) + self.alt_integ;
        let tilt = (x[idx::PHI].cos() * x[idx::THETA].cos()).max(0.5);
        let factor = ((1.0 + a_des / g) / tilt).clamp(0.2, 2.5);
        let throttle = 1000.0 + (self.hover_throttle - 1000.0) * factor.sqrt();
        // Loose position and attitude hold from what the pilot sees.
        let (ss, cs) = x[idx::PSI].sin_cos();
        let v_fwd = cs * x[idx::VX] + ss * x[idx::VY];
        let v_right = -ss * x[idx::VX] + cs * x[idx::VY];
        let e_fwd = cs * x[idx::X] + ss * x[idx::Y];
        let e_right = -ss * x[idx::X] + cs * x[idx::Y];
        let (kv, kp) = (0.08, 0.02);
        let phi_des = self.phi_trim - (kv * v_right + kp * e_right).clamp(-0.25, 0.25);
        let theta_des = (kv * v_fwd + kp * e_fwd).clamp(-0.25, 0.25);
        let psi_err = (0.0 - x[idx::PSI] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        let reference = [
            2.5 * (phi_des - x[idx::PHI]) + exc[0],
            2.5 * (theta_des - x[idx::THETA]) + exc[1],
            1.0 * psi_err + exc[2],
        ];
        (reference, throttle)
    }
}

/// Longest flight [`simulate`] flies, in seconds: 10,000 s (2.8 h, 500,000
/// log rows, about 130 MB held in memory and 300 MB of CSV).
pub const MAX_SIM_SECONDS: f64 = 10_000.0;

/// Most RK4 integration steps (`seconds / dt`) [`simulate`] takes: `1e8`,
/// one to two minutes (the default 250 s at 1 ms take 250,000).
pub const MAX_SIM_STEPS: f64 = 1e8;

/// Flies one experiment and returns its log.
///
/// A flight longer than [`MAX_SIM_SECONDS`] or needing more than
/// [`MAX_SIM_STEPS`] integration steps is refused with
/// [`ModelError::TooLarge`] before it starts.
///
/// ```
/// use kestrel_tricopter_model::{Experiment, SimSettings, simulate};
/// let log = simulate(&SimSettings::new(Experiment::Hover, 20.0, 1)).unwrap();
/// assert_eq!(log.rows.len(), 1000);                 // 20 s at 50 Hz
/// let (t0, t1) = log.airborne_intervals()[0];
/// assert!(t0 < 4.0 && t1 > 15.0);                   // take-off and landing
/// ```
pub fn simulate(settings: &SimSettings) -> Result<FlightLog, ModelError> {
    if !(settings.seconds.is_finite() && settings.seconds > 0.0) {
        return Err(ModelError::InvalidSetting {
            name: "seconds",
            reason: format!("must be finite and positive, found {}", settings.seconds),
        });
    }
    check_size(settings)?;
    if !(settings.hover_altitude.is_finite() && settings.hover_altitude > 0.0) {
        return Err(ModelError::InvalidSetting {
            name: "hover_altitude",
            reason: format!(
                "must be finite and positive, found {}",
                settings.hover_altitude
            ),
        });
    }
    if !settings
        .excitation
        .iter()
        .all(|a| a.is_finite() && *a >= 0.0)
    {
        return Err(ModelError::InvalidSetting {
            name: "excitation",
            reason: "amplitudes must be finite and >= 0".into(),
        });
    }
    let mut plant = Plant::new(settings.plant, settings.seed)?;
    let trim = plant.model().trim_hover()?;
    let g = settings.gains;
    if ![g.dt, g.throttle_cut]
        .iter()
        .chain(&g.kp)
        .chain(&g.ki)
        .chain(&g.imax)
        .all(|v| v.is_finite())
    {
        return Err(ModelError::InvalidSetting {
            name: "gains",
            reason: "must be finite".into(),
        });
    }
    let mut gains = settings.gains;
    gains.dt = plant.sample_time();
    let mixer = Mixer::new([0.0, 0.0, 0.0, settings.plant.params.servo_center]);
    let mut pid = RatePid::new(gains, mixer);
    let base = settings.seed.wrapping_mul(0x2545_F491_4F6C_DD1D);
    let mut pilot = Pilot {
        settings: *settings,
        hover_throttle: trim.throttle,
        phi_trim: trim.phi,
        alt_integ: 0.0,
        excitation: core::array::from_fn(|i| Excitation::new(base ^ (0xA5A5 + i as u64))),
        cut: false,
    };
    let n = (settings.seconds * settings.plant.gyro.rate_hz + 1e-9).floor() as usize;
    let mut rows = Vec::with_capacity(n);
    for _ in 0..n {
        let t = plant.time();
        let y = plant.measure();
        let airborne = plant.airborne();
        let x = *plant.state();
        let (reference, throttle) = pilot.command(t, &x, airborne);
        let out = pid
            .update(&y, &reference, throttle)
            .map_err(ModelError::Core)?;
        let v = pid.last_virtual();
        rows.push(LogRow {
            t,
            pwm: out.pwm,
            throttle,
            virtual_input: [v.roll, v.pitch, v.yaw],
            gyro: y,
            reference,
            state: x,
            airborne,
        });
        plant.advance(&out.pwm)?;
    }
    Ok(FlightLog {
        settings: *settings,
        trim,
        rows,
    })
}

/// Refuses a flight beyond [`MAX_SIM_SECONDS`] or [`MAX_SIM_STEPS`].
fn check_size(settings: &SimSettings) -> Result<(), ModelError> {
    let (seconds, dt) = (settings.seconds, settings.plant.dt);
    let rows = seconds * settings.plant.gyro.rate_hz;
    if seconds > MAX_SIM_SECONDS {
        return Err(ModelError::TooLarge {
            what: format!("a flight of {seconds} s"),
            cost: format!(
                "{rows:.0} log rows, about {:.1} GB in memory and as CSV",
                rows * 900.0 / 1e9
            ),
            limit: format!("at most {MAX_SIM_SECONDS} s"),
        });
    }
    let steps = seconds / dt;
    if dt.is_finite() && dt > 0.0 && steps > MAX_SIM_STEPS {
        return Err(ModelError::TooLarge {
            what: format!("integration with dt = {dt} s over {seconds} s"),
            cost: format!(
                "{steps:.1e} RK4 steps, about {:.1} hours",
                steps / 1e6 / 3600.0
            ),
            limit: format!("at most {MAX_SIM_STEPS:.0e} steps"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::{THESIS_GYRO_BIAS, THESIS_GYRO_COVARIANCE};

    fn in_window(log: &FlightLog, t0: f64, t1: f64) -> impl Iterator<Item = &LogRow> {
        log.rows.iter().filter(move |r| r.t >= t0 && r.t <= t1)
    }

    #[test]
    fn hover_with_noise_stays_level_for_60_s() {
        let log = simulate(&SimSettings::new(Experiment::Hover, 70.0, 3)).unwrap();
        let phi0 = log.trim.phi;
        // 60 s of hover after the climb (5-65 s).
        let mut n = 0;
        for r in in_window(&log, 5.0, 65.0) {
            assert!(r.airborne, "landed at {}", r.t);
            let x = &r.state;
            assert!(
                (x[idx::PHI] - phi0).abs() < 3f64.to_radians(),
                "phi {} at {}",
                x[idx::PHI],
                r.t
            );
            assert!(
                x[idx::THETA].abs() < 3f64.to_radians(),
                "theta {} at {}",
                x[idx::THETA],
                r.t
            );
            assert!(x[idx::P].abs() < 0.3 && x[idx::Q].abs() < 0.3 && x[idx::R].abs() < 0.3);
            assert!(
                (-x[idx::Z] - 1.5).abs() < 0.3,
                "altitude {} at {}",
                -x[idx::Z],
                r.t
            );
            n += 1;
        }
        assert_eq!(n, 3001);
        // The gyro really was noisy (measured minus true rate spreads like (7.6)).
        let var: f64 = in_window(&log, 5.0, 65.0)
            .map(|r| (r.gyro[2] - r.state[idx::R] - THESIS_GYRO_BIAS[2]).powi(2))
            .sum::<f64>()
            / n as f64;
        assert!(var > 0.5 * THESIS_GYRO_COVARIANCE[2][2]);
    }

    #[test]
    fn ground_experiment_reproduces_bias_and_covariance() {
        let settings = SimSettings::new(Experiment::Ground, 250.0, 5);
        let log = simulate(&settings).unwrap();
        assert!(
            log.rows
                .iter()
                .all(|r| !r.airborne && r.state[idx::P] == 0.0)
        );
        let n = log.rows.len() as f64;
        let mut mean = [0.0; 3];
        for r in &log.rows {
            for i in 0..3 {
                mean[i] += r.gyro[i] / n;
            }
        }
        let mut cov = [[0.0; 3]; 3];
        for r in &log.rows {
            for i in 0..3 {
                for j in 0..3 {
                    cov[i][j] += (r.gyro[i] - mean[i]) * (r.gyro[j] - mean[j]) / (n - 1.0);
                }
            }
        }
        let q = settings.plant.gyro.quantum;
        let r = THESIS_GYRO_COVARIANCE;
        for i in 0..3 {
            // Mean within 4 standard errors of the bias.
            let se = ((r[i][i] + q * q / 12.0) / n).sqrt();
            assert!(
                (mean[i] - THESIS_GYRO_BIAS[i]).abs() < 4.0 * se,
                "mean {i}: {} vs {}",
                mean[i],
                THESIS_GYRO_BIAS[i]
            );
            for j in 0..3 {
                // Quantisation adds q^2/12 on the diagonal (Sheppard's correction).
                let want = r[i][j] + if i == j { q * q / 12.0 } else { 0.0 };
                let wii = r[i][i] + q * q / 12.0;
                let wjj = r[j][j] + q * q / 12.0;
                // Standard error of a sample covariance of Gaussian data.
                let se = ((wii * wjj + want * want) / n).sqrt();
                assert!(
                    (cov[i][j] - want).abs() < 4.0 * se,
                    "cov {i}{j}: {} vs {want} (se {se})",
                    cov[i][j]
                );
            }
        }
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_bytes() {
        let s = SimSettings::new(Experiment::Coupled, 30.0, 1);
        let a = simulate(&s).unwrap().to_csv_bytes().unwrap();
        let b = simulate(&s).unwrap().to_csv_bytes().unwrap();
        assert_eq!(a, b);
        let c = simulate(&SimSettings { seed: 2, ..s })
            .unwrap()
            .to_csv_bytes()
            .unwrap();
        assert_ne!(a, c);
        let text = String::from_utf8(a).unwrap();
        let header = text.lines().next().unwrap();
        assert_eq!(header, LOG_COLUMNS.join(","));
        assert_eq!(text.lines().count(), 1 + 1500);
        // Every field parses back to a finite number.
        for line in text.lines().skip(1).step_by(97) {
            let fields: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
            assert_eq!(fields.len(), LOG_COLUMNS.len());
            assert!(fields.iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn coupled_flight_covers_the_thesis_intervals_with_excitation() {
        let log = simulate(&SimSettings::new(Experiment::Coupled, 250.0, 1)).unwrap();
        let air = log.airborne_intervals();
        assert_eq!(air.len(), 1, "{air:?}");
        assert!(air[0].0 < 5.0 && air[0].1 > 247.0, "{air:?}");
        for (t0, t1) in [(21.28, 42.82), (108.9, 165.8), (181.66, 219.6)] {
            let rows: Vec<&LogRow> = in_window(&log, t0, t1).collect();
            assert!(rows.iter().all(|r| r.airborne));
            for i in 0..3 {
                let m = rows.iter().map(|r| r.gyro[i]).sum::<f64>() / rows.len() as f64;
                let sd = (rows.iter().map(|r| (r.gyro[i] - m).powi(2)).sum::<f64>()
                    / rows.len() as f64)
                    .sqrt();
                assert!(sd > 0.2, "axis {i} in ({t0}, {t1}): sd {sd}");
            }
            // No excursion beyond 45 degrees, no motor saturation.
            assert!(
                rows.iter()
                    .all(|r| r.state[idx::PHI].abs() < 0.8 && r.state[idx::THETA].abs() < 0.8)
            );
            assert!(
                rows.iter()
                    .all(|r| r.pwm[..3].iter().all(|p| *p > 1000.0 && *p < 2000.0))
            );
        }
        // Landed and stopped at the end.
        let last = log.rows.last().unwrap();
        assert!(!last.airborne && last.pwm[..3] == [1000.0; 3]);
    }

    #[test]
    fn decoupled_flight_excites_one_axis_at_a_time() {
        let log = simulate(&SimSettings::new(Experiment::Decoupled, 40.0, 4)).unwrap();
        // Segments: roll 10-16 s, pitch 18-24 s, yaw 26-32 s.
        for (axis, t0) in [(0usize, 10.5), (1, 18.5), (2, 26.5)] {
            let rows: Vec<&LogRow> = in_window(&log, t0, t0 + 5.0).collect();
            let energy: Vec<f64> = (0..3)
                .map(|i| rows.iter().map(|r| r.reference[i].powi(2)).sum::<f64>())
                .collect();
            for i in 0..3 {
                if i != axis {
                    assert!(energy[axis] > 10.0 * energy[i], "axis {axis}: {energy:?}");
                }
            }
        }
    }

    #[test]
    fn bad_settings_are_errors() {
        assert!(
            "spiral"
                .parse::<Experiment>()
                .unwrap_err()
                .to_string()
                .contains("hover, decoupled")
        );
        for e in Experiment::ALL {
            assert_eq!(e.name().parse::<Experiment>().unwrap(), e);
        }
        let s = SimSettings::new(Experiment::Hover, 10.0, 1);
        for bad in [f64::NAN, -1.0, 0.0, f64::INFINITY] {
            assert!(simulate(&SimSettings { seconds: bad, ..s }).is_err());
        }
        // Too long or too finely integrated: refused before it starts.
        assert!(matches!(
            simulate(&SimSettings { seconds: 1e6, ..s }),
            Err(ModelError::TooLarge { .. })
        ));
        let mut fine = s;
        fine.plant.dt = 1e-9;
        let e = simulate(&fine).unwrap_err();
        assert!(matches!(e, ModelError::TooLarge { .. }), "{e}");
        let mut d = s;
        d.plant.dt = 0.003;
        assert!(matches!(
            simulate(&d),
            Err(ModelError::InvalidSetting { name: "dt", .. })
        ));
        let mut m = s;
        m.plant.params.mass = f64::NAN;
        assert!(matches!(
            simulate(&m),
            Err(ModelError::InvalidParam { name: "mass", .. })
        ));
        let mut g = s;
        g.gains.kp[0] = f64::NAN;
        assert!(simulate(&g).is_err());
    }
}
