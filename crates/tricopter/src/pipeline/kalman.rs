//! Stage 4: the stationary Kalman filter of section 7.5, the one the
//! closed loop flies and the firmware carries.
//!
//! The filter's model is the MPC's estimator model (stage 5): the
//! identified black-box model, with `mpc.offset_free` augmented with the
//! MPC's disturbance states, so the filter's state is the `x` (and `d`)
//! of the MPC's `theta`. Process noise enters through `[B, C', 0; 0, 0, I]`
//! (`kalman.input_noise` per pulse, a rate noise along the measured
//! directions and a random walk on the disturbances), the measurement
//! noise is the gyro covariance of stage 2 and the filter removes the gyro
//! bias of stage 2. The rate and disturbance noise are chosen on
//! `kalman.training_flight` by innovation consistency: the mean normalised
//! innovation squared (NIS) closest to 1.

use super::config::Config;
use super::error::{Context, PipelineError, Result};
use super::experiments::{Experiments, Flight};
use super::filter::{WithFilter, with_filter};
use super::problems::Problems;
use super::sensor::SensorStats;
use kestrel_kalman::{AugmentedModel, DisturbanceDesign, DisturbanceNoise, StationaryFilter};
use nalgebra::DVector;

/// One point of the noise grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NisPoint {
    /// Rate noise (rad/s per sample).
    pub rate_noise: f64,
    /// Disturbance (gust) noise (rad/s per sample); `None` without
    /// disturbance states.
    pub gust_noise: Option<f64>,
    /// Mean NIS on the training flight.
    pub nis: f64,
}

/// RMS errors against the simulator's true body rates over the airborne
/// part of the filtered flight (rad/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KalmanRms {
    /// The gyro minus its bias.
    pub gyro: [f64; 3],
    /// The filter's output estimate.
    pub kalman: [f64; 3],
}

/// Stage 4's result: the tuned filter.
#[derive(Clone, Debug)]
pub struct KalmanStage {
    /// The design: the estimator model (with its disturbance maps) and the
    /// stationary filter (`design.kalman`, `kestrel.kalman.v1`).
    pub design: DisturbanceDesign,
    /// Pulse noise (us).
    pub input_noise: f64,
    /// The chosen point of the grid.
    pub chosen: NisPoint,
    /// The whole grid.
    pub grid: Vec<NisPoint>,
    /// The training flight.
    pub training_flight: u8,
    /// The filtered flight.
    pub flight: u8,
    /// Mean NIS on the filtered flight.
    pub flight_nis: f64,
    /// Output estimates `C x + y0` over the filtered flight.
    pub estimate: Vec<[f64; 3]>,
    /// Errors against the true rates (simulated flights).
    pub rms: Option<KalmanRms>,
}

impl KalmanStage {
    /// The measurement-update gain `M` (`nx x 3`).
    pub fn gain(&self) -> &nalgebra::DMatrix<f64> {
        &self.design.kalman.filter.m
    }
}

/// Runs a filter over a flight: output estimates and mean NIS.
struct OverFlight<'a> {
    flight: &'a Flight,
    s_inv: nalgebra::DMatrix<f64>,
}

impl WithFilter for OverFlight<'_> {
    type Output = (Vec<[f64; 3]>, f64);
    fn run<const NX: usize>(
        self,
        mut filt: StationaryFilter<f64, NX, 4, 3>,
    ) -> Result<Self::Output> {
        let f = self.flight;
        let ny = self.s_inv.nrows() as f64;
        let mut out = Vec::with_capacity(f.t.len());
        let (mut nis, mut n) = (0.0, 0usize);
        for k in 0..f.t.len() {
            filt.update(&f.gyro[k])
                .ctx(|| format!("Kalman update at t = {}", f.t[k]))?;
            if f.airborne[k] {
                let e = DVector::from_column_slice(filt.innovation());
                nis += (e.transpose() * &self.s_inv * &e)[(0, 0)] / ny;
                n += 1;
            }
            out.push(filt.output_estimate());
            filt.predict(&f.pwm[k])
                .ctx(|| format!("Kalman time update at t = {}", f.t[k]))?;
        }
        if n == 0 {
            return Err(PipelineError::Data(format!(
                "flight no. {} ({}): no airborne samples (its `airborne` column is 0 throughout); \
                 the filter's mean NIS is taken over the airborne part of a flight",
                f.experiment.number(),
                f.experiment.name()
            )));
        }
        Ok((out, nis / n as f64))
    }
}

/// The filter over a flight with the logged pulses: output estimates and
/// the mean normalised innovation squared `e' S^-1 e / ny` over the
/// airborne samples.
///
/// # Errors
/// A singular innovation covariance; a flight with no airborne sample; the
/// filter's errors.
pub fn filter_flight(
    design: &kestrel_kalman::KalmanDesign,
    flight: &Flight,
) -> Result<(Vec<[f64; 3]>, f64)> {
    let s_inv = design
        .filter
        .innovation_covariance
        .clone()
        .try_inverse()
        .ok_or_else(|| PipelineError::Data("the innovation covariance is singular".into()))?;
    with_filter(design, OverFlight { flight, s_inv })
}

/// The filter of the estimator model with the given noise levels.
///
/// # Errors
/// kestrel-kalman's errors.
pub fn design(
    aug: &AugmentedModel,
    s: &SensorStats,
    input_noise: f64,
    rate_noise: f64,
    gust_noise: f64,
) -> Result<DisturbanceDesign> {
    let mut noise = DisturbanceNoise::inputs_and_outputs(
        aug,
        input_noise,
        rate_noise,
        gust_noise,
        s.covariance.clone(),
    );
    noise.bias = Some(DVector::from_column_slice(&s.bias));
    aug.design(&noise)
        .ctx(|| "dlqe on the black-box model with its disturbance states".into())
}

/// Stage 4 (after stage 5, whose estimator model it filters).
///
/// # Errors
/// A missing flight; kestrel-kalman's errors.
pub fn run(cfg: &Config, ex: &Experiments, s: &SensorStats, pr: &Problems) -> Result<KalmanStage> {
    let k = &cfg.kalman;
    // The bias is removed by the filter; y0 keeps the rest of the offset.
    let mut model = pr.estimator_model.clone();
    let bias = DVector::from_column_slice(&s.bias);
    let y0 = model
        .y0
        .clone()
        .unwrap_or_else(|| DVector::zeros(model.ny()));
    model.y0 = Some(&y0 - &bias);
    let aug = AugmentedModel::from_augmented(&model, pr.nd)
        .ctx(|| "the estimator model's disturbance states".into())?;
    let train = ex.flight(k.training_flight, "kalman.training_flight")?;
    let gusts: Vec<Option<f64>> = if pr.nd > 0 {
        k.gust_noise.iter().map(|g| Some(*g)).collect()
    } else {
        vec![None]
    };
    let mut grid = Vec::new();
    for &rate in &k.rate_noise {
        for &gust in &gusts {
            let d = design(&aug, s, k.input_noise, rate, gust.unwrap_or(0.0))?;
            let (_, nis) = filter_flight(&d.kalman, train)?;
            grid.push(NisPoint {
                rate_noise: rate,
                gust_noise: gust,
                nis,
            });
        }
    }
    let chosen = grid
        .iter()
        .copied()
        .reduce(|b, p| {
            if (p.nis - 1.0).abs() < (b.nis - 1.0).abs() {
                p
            } else {
                b
            }
        })
        .ok_or_else(|| {
            PipelineError::config_message(
                "kalman.rate_noise / kalman.gust_noise: empty grid".into(),
            )
        })?;
    let design = design(
        &aug,
        s,
        k.input_noise,
        chosen.rate_noise,
        chosen.gust_noise.unwrap_or(0.0),
    )?;
    let f = ex.flight(k.flight, "kalman.flight")?;
    let (estimate, flight_nis) = filter_flight(&design.kalman, f)?;
    let rms = f.truth.as_ref().map(|truth| {
        let idx: Vec<usize> = (0..f.t.len()).filter(|&k| f.airborne[k]).collect();
        let rms = |g: &dyn Fn(usize) -> [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|j| {
                (idx.iter()
                    .map(|&k| (g(k)[j] - truth[k][j]).powi(2))
                    .sum::<f64>()
                    / idx.len() as f64)
                    .sqrt()
            })
        };
        KalmanRms {
            gyro: rms(&|k| std::array::from_fn(|j| f.gyro[k][j] - s.bias[j])),
            kalman: rms(&|k| estimate[k]),
        }
    });
    Ok(KalmanStage {
        design,
        input_noise: k.input_noise,
        chosen,
        grid,
        training_flight: k.training_flight,
        flight: k.flight,
        flight_nis,
        estimate,
        rms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::config::Experiments as ExperimentsConfig;
    use kestrel_core::formats::SsModel;
    use kestrel_kalman::{KalmanDesign, NoiseModel};
    use kestrel_tricopter_model::Experiment;
    use nalgebra::DMatrix;

    /// A flight whose `airborne` column is 0 throughout has no sample to
    /// take the mean NIS over: an error naming the flight, not a NIS of 0
    /// (which the noise grid would then have chosen from silently).
    #[test]
    fn a_flight_never_airborne_is_refused_by_name() {
        let cfg = ExperimentsConfig {
            seconds: 6.0,
            seed: 1,
            dt: 0.001,
        };
        let mut flight = Flight::simulate(Experiment::Hover, &cfg).unwrap();
        // One decoupled state per output, driven by the four pulses.
        let model = SsModel::new(
            0.02,
            DMatrix::identity(3, 3) * 0.9,
            DMatrix::from_element(3, 4, 1e-4),
            DMatrix::identity(3, 3),
            DMatrix::zeros(3, 4),
        )
        .unwrap();
        let design = KalmanDesign::new(&model, &NoiseModel::isotropic(3, 3, 1e-4, 1e-4)).unwrap();
        let airborne = flight.airborne.iter().filter(|a| **a).count();
        assert!(airborne > 10, "{airborne} airborne samples");
        let (estimate, nis) = filter_flight(&design, &flight).unwrap();
        assert_eq!(estimate.len(), flight.t.len());
        assert!(nis.is_finite() && nis > 0.0, "NIS {nis}");
        flight.airborne.fill(false);
        let err = filter_flight(&design, &flight).unwrap_err().to_string();
        assert!(
            err.contains("flight no. 1 (hover)") && err.contains("no airborne samples"),
            "{err}"
        );
    }
}
