//! Section 7.4 of the thesis on the simulated tricopter: the black-box and
//! black-box virtual rate models from flights no. 2 and 3 of
//! `kestrel-tricopter-model`, on the thesis's estimation and validation sets.

use crate::error::sysid_invalid;
use kestrel_sysid::workflow::{
    IdentifyReport, IdentifySpec, InputMap, PemFocus, Segment, identify,
};
use kestrel_sysid::{Experiment, IoData, Result};
use kestrel_tricopter_model::{
    C_PITCH, C_ROLL, C_YAW, Experiment as Flight, SimSettings, simulate,
};
use nalgebra::DMatrix;

/// Estimation set of the black-box models (section 7.2.2): flight no. 2
/// (experiment 1 here) `(25.66, 50.28)`, `(50.46, 71.80)`, flight no. 3
/// (experiment 2) `(108.90, 165.80)`.
pub const ESTIMATE: &str = "1@25.66:50.28,1@50.46:71.80,2@108.9:165.8";

/// Validation set of the black-box models: flight no. 2 `(102.94, 126.12)`,
/// flight no. 3 `(21.28, 42.82)`, `(181.66, 219.60)`, `(227.28, 246.0)`
/// (the thesis's last interval ends at 249.84 s; the simulated flight
/// lands in its last 3.5 s, so it ends at 246 s here).
pub const VALIDATE: &str = "1@102.94:126.12,2@21.28:42.82,2@181.66:219.6,2@227.28:246";

/// The thesis's (flight no. 2 only) estimation set of the virtual model.
pub const VIRTUAL_ESTIMATE_THESIS: &str = "1@25.66:37.96,1@54.48:62.64,1@101.5:111.44";

/// The thesis's (flight no. 2 only) validation set of the virtual model.
pub const VIRTUAL_VALIDATE_THESIS: &str = "1@37.98:50.28,1@62.66:70.8,1@111.5:121.4";

/// Which of the thesis's black-box models.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelKind {
    /// Inputs `pwm1, pwm2, pwm3, servo` (us).
    BlackBox,
    /// Inputs through the mixer: `u_roll, u_pitch, u_yaw` (us).
    Virtual,
}

/// The black-box virtual model's input map of the thesis: motor 1, 2, 3
/// and servo pulses to `(U_r, U_p, U_y)` through the inverse of the mixer
/// (3.28) with `C_r = 1/sqrt(3)`, `C_p = 2/3`, `C_y = 1`; the new inputs
/// are named `u_roll, u_pitch, u_yaw`.
///
/// ```
/// use nalgebra::DVector;
/// // Roll moves motors 2 and 3 in opposite directions, pitch the rear
/// // against the front, yaw is the servo.
/// let m = kestrel_tricopter::ident::virtual_input_map().matrix;
/// let v = &m * DVector::from_vec(vec![0.0, 1.0, -1.0, 0.0]);
/// assert!(v[0] > 0.0 && v[1].abs() < 1e-15 && v[2] == 0.0);
/// ```
pub fn virtual_input_map() -> InputMap {
    let (cr, cp) = (C_ROLL, C_PITCH);
    #[rustfmt::skip]
    let matrix = DMatrix::from_row_slice(3, 4, &[
        0.0, cr, -cr, 0.0,
        -cp, cp / 2.0, cp / 2.0, 0.0,
        0.0, 0.0, 0.0, C_YAW,
    ]);
    InputMap {
        matrix,
        names: vec!["u_roll".into(), "u_pitch".into(), "u_yaw".into()],
    }
}

/// Flights no. 2 (`decoupled`) and no. 3 (`coupled`) of the simulator, as
/// two experiments with inputs `pwm1, pwm2, pwm3, servo` and outputs the
/// gyro's `p, q, r` (the same samples `kestrel simulate` writes).
pub fn simulated_flights(seconds: f64, seed: u64) -> Result<IoData> {
    let mut exps = Vec::with_capacity(2);
    for flight in [Flight::Decoupled, Flight::Coupled] {
        let log = simulate(&SimSettings::new(flight, seconds, seed))
            .map_err(|e| sysid_invalid(format!("simulating {}: {e}", flight.name())))?;
        let n = log.rows.len();
        exps.push(Experiment {
            t: log.rows.iter().map(|r| r.t).collect(),
            u: DMatrix::from_fn(n, 4, |k, j| log.rows[k].pwm[j]),
            y: DMatrix::from_fn(n, 3, |k, j| log.rows[k].gyro[j]),
        });
    }
    let ts = 1.0
        / SimSettings::new(Flight::Decoupled, seconds, seed)
            .plant
            .gyro
            .rate_hz;
    IoData::from_experiments(
        ts,
        ["pwm1", "pwm2", "pwm3", "servo"].map(String::from).to_vec(),
        ["p", "q", "r"].map(String::from).to_vec(),
        exps,
    )
}

/// The identification of section 7.4 as an [`IdentifySpec`]: order 8 by
/// PEM reduced to 5 by `balred` with matched DC gain (MATLAB's default
/// `StateElimMethod = 'MatchDC'`, so the thesis's `balred(mod8, 5)`), on
/// [`ESTIMATE`] / [`VALIDATE`], with the focus [`PemFocus::SimulationThenNoise`].
///
/// Why that focus: the rate dynamics are integrators (torque to rate) and
/// the flights are flown in closed loop with gusts, so the one-step
/// optimum puts poles at `z ~ 1` and its open-loop simulation drifts
/// (simulation fit ~25 % on validation); fitting `A, B, C` on simulation
/// errors and then only `K` on one-step errors keeps the simulation fit
/// of an output-error model and the k-step fits of a Kalman predictor.
/// The virtual model uses the black-box sets: the thesis's flight-2-only
/// sets ([`VIRTUAL_ESTIMATE_THESIS`]) hold too little yaw excitation in
/// the simulated flight and give a negative `r` fit.
pub fn thesis_spec(kind: ModelKind) -> IdentifySpec {
    IdentifySpec {
        estimate: Segment::parse_list(ESTIMATE).unwrap_or_default(),
        validate: Segment::parse_list(VALIDATE).unwrap_or_default(),
        order: Some(8),
        reduce: Some(5),
        match_dc: true,
        focus: PemFocus::SimulationThenNoise,
        input_map: match kind {
            ModelKind::BlackBox => None,
            ModelKind::Virtual => Some(virtual_input_map()),
        },
        // The thesis's structure, as given (no automatic choice), and its
        // tables (no ARX rows).
        auto: None,
        arx_baseline: None,
        ..Default::default()
    }
}

/// [`thesis_spec`] run on [`simulated_flights`].
///
/// ```no_run
/// use kestrel_tricopter::ident::{identify_thesis_model, ModelKind};
/// let report = identify_thesis_model(ModelKind::BlackBox, 250.0, 1).unwrap();
/// println!("{report}");
/// ```
pub fn identify_thesis_model(kind: ModelKind, seconds: f64, seed: u64) -> Result<IdentifyReport> {
    identify(&simulated_flights(seconds, seed)?, &thesis_spec(kind))
}

/// A plain prediction-focus spec (for comparison with [`thesis_spec`]).
pub fn prediction_spec(kind: ModelKind) -> IdentifySpec {
    IdentifySpec {
        focus: PemFocus::Prediction,
        ..thesis_spec(kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Done-when 1 of issue 4 on the simulator: both models of order 8
    /// reduced to 5 beat the thesis's tables (simulation 41-59 %, 5-step
    /// 31-60 %) and the persistence baseline on the validation set, and
    /// the table carries the residual verdicts. Thresholds sit a few
    /// points under the measured values (README) to allow for rounding
    /// differences across platforms, not for a worse model.
    #[test]
    fn thesis_models_fit_the_validation_flights() {
        let flights = simulated_flights(250.0, 1).unwrap();
        assert_eq!(flights.experiments().len(), 2);
        assert_eq!(flights.ts(), 0.02);
        for kind in [ModelKind::BlackBox, ModelKind::Virtual] {
            let r = identify(&flights, &thesis_spec(kind)).unwrap();
            assert_eq!((r.model.nx(), r.full_model.nx()), (5, 8));
            assert_eq!(
                r.model.nu(),
                if kind == ModelKind::BlackBox { 4 } else { 3 }
            );
            let v = &r.validation;
            let row = |l: &str| v.row(l).unwrap().fit.clone();
            let (sim, one, five) = (
                row("model simulation"),
                row("model 1-step"),
                row("model 5-step"),
            );
            let (p1, p5) = (row("persistence 1-step"), row("persistence 5-step"));
            for o in 0..3 {
                assert!(
                    sim[o] > 50.0,
                    "{kind:?} output {o}: simulation fit {}\n{r}",
                    sim[o]
                );
                assert!(
                    five[o] > 80.0 && five[o] > p5[o] + 20.0,
                    "{kind:?} output {o}: 5-step\n{r}"
                );
                assert!(
                    one[o] > 93.0 && one[o] > p1[o],
                    "{kind:?} output {o}: 1-step\n{r}"
                );
            }
            assert_eq!(v.residuals.outputs.len(), 3);
            assert_eq!(v.residuals.max_lag, 25);
            // The stable 5-state model is what the MPC crates design from.
            assert!(r.model.radius_a() < 1.0);
        }
    }
}
