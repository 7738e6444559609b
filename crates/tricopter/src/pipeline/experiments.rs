//! Stage 1: the four flights of section 7.1, simulated by
//! kestrel-tricopter-model or given (parsed from logs by the caller).

use super::config::{Config, Experiments as ExperimentsConfig, Interval};
use super::error::{Context, PipelineError, Result};
use kestrel_sysid::workflow::Segment;
use kestrel_sysid::{Experiment as SysidExperiment, IoData, TimeInterval};
use kestrel_tricopter_model::{Experiment, SimSettings};
use nalgebra::DMatrix;

/// One flight log, column by column.
#[derive(Clone, Debug)]
pub struct Flight {
    /// The experiment (1 hover, 2 decoupled, 3 coupled, 4 ground).
    pub experiment: Experiment,
    /// Sample times (s).
    pub t: Vec<f64>,
    /// `[pwm1, pwm2, pwm3, servo]` (us).
    pub pwm: Vec<[f64; 4]>,
    /// Pilot throttle (us).
    pub throttle: Vec<f64>,
    /// Mixer virtual inputs `[U_r, U_p, U_y]` (us).
    pub virtual_input: Vec<[f64; 3]>,
    /// Gyro `[p, q, r]` (rad/s).
    pub gyro: Vec<[f64; 3]>,
    /// True body rates when known (simulated flights).
    pub truth: Option<Vec<[f64; 3]>>,
    /// Whether the aircraft is off the ground.
    pub airborne: Vec<bool>,
    /// The true hover trim offsets `U_0` when known (simulated flights).
    pub true_offsets: Option<[f64; 4]>,
    /// The log as CSV text in the simulator's columns (what a report
    /// stores beside its tables).
    pub csv: Vec<u8>,
}

/// The file name of a flight in a report or a flight-log directory.
pub fn file_name(e: Experiment) -> String {
    format!("flight-{}-{}.csv", e.number(), e.name())
}

impl Flight {
    /// Simulates experiment `e` with the configured length and seed
    /// (`seed + k - 1` for experiment `k`).
    ///
    /// # Errors
    /// The simulator's errors.
    pub fn simulate(e: Experiment, cfg: &ExperimentsConfig) -> Result<Self> {
        let seed = cfg.seed + u64::from(e.number()) - 1;
        let mut settings = SimSettings::new(e, cfg.seconds, seed);
        settings.plant.dt = cfg.dt;
        let log = kestrel_tricopter_model::simulate(&settings)
            .ctx(|| format!("simulating experiment {} ({})", e.number(), e.name()))?;
        let csv = log
            .to_csv_bytes()
            .ctx(|| format!("experiment {} as CSV", e.number()))?;
        let rows = &log.rows;
        Ok(Flight {
            experiment: e,
            t: rows.iter().map(|r| r.t).collect(),
            pwm: rows.iter().map(|r| r.pwm).collect(),
            throttle: rows.iter().map(|r| r.throttle).collect(),
            virtual_input: rows.iter().map(|r| r.virtual_input).collect(),
            gyro: rows.iter().map(|r| r.gyro).collect(),
            truth: Some(
                rows.iter()
                    .map(|r| {
                        let x = &r.state;
                        [
                            x[kestrel_tricopter_model::idx::P],
                            x[kestrel_tricopter_model::idx::Q],
                            x[kestrel_tricopter_model::idx::R],
                        ]
                    })
                    .collect(),
            ),
            airborne: rows.iter().map(|r| r.airborne).collect(),
            true_offsets: Some(log.trim.offsets),
            csv,
        })
    }

    /// Sample time (s).
    pub fn ts(&self) -> f64 {
        (self.t[self.t.len() - 1] - self.t[0]) / (self.t.len() - 1) as f64
    }

    /// Seconds off the ground.
    pub fn airborne_seconds(&self) -> f64 {
        self.airborne.iter().filter(|a| **a).count() as f64 * self.ts()
    }

    /// Standard deviation of each gyro axis over the whole log (rad/s).
    pub fn gyro_std(&self) -> [f64; 3] {
        let n = self.gyro.len() as f64;
        std::array::from_fn(|j| {
            let m = self.gyro.iter().map(|g| g[j]).sum::<f64>() / n;
            (self.gyro.iter().map(|g| (g[j] - m).powi(2)).sum::<f64>() / n).sqrt()
        })
    }

    /// The flight as an identification data set: inputs the four pulses
    /// (`virtual_inputs`: the three mixer inputs), outputs the gyro.
    ///
    /// # Errors
    /// kestrel-sysid's errors (e.g. non-increasing times).
    pub fn io_data(&self, virtual_inputs: bool) -> Result<IoData> {
        let n = self.t.len();
        let (u, names): (DMatrix<f64>, Vec<String>) = if virtual_inputs {
            (
                DMatrix::from_fn(n, 3, |i, j| self.virtual_input[i][j]),
                vec!["u_roll".into(), "u_pitch".into(), "u_yaw".into()],
            )
        } else {
            (
                DMatrix::from_fn(n, 4, |i, j| self.pwm[i][j]),
                vec!["pwm1".into(), "pwm2".into(), "pwm3".into(), "servo".into()],
            )
        };
        let y = DMatrix::from_fn(n, 3, |i, j| self.gyro[i][j]);
        IoData::from_experiments(
            self.ts(),
            names,
            vec!["p".into(), "q".into(), "r".into()],
            vec![SysidExperiment {
                t: self.t.clone(),
                u,
                y,
            }],
        )
        .ctx(|| format!("flight {} as identification data", self.experiment.number()))
    }
}

/// The data set of the given intervals, each an experiment of its own
/// (MATLAB's `merge`); `key` names the configuration list in errors.
///
/// # Errors
/// A missing flight, an interval reaching beyond its flight's samples
/// (by more than half a sample period).
pub fn select(
    flights: &[Flight],
    intervals: &[Interval],
    virtual_inputs: bool,
    key: &str,
) -> Result<IoData> {
    let mut parts = Vec::new();
    for (i, iv) in intervals.iter().enumerate() {
        let f = flights
            .iter()
            .find(|f| f.experiment.number() == iv.flight)
            .ok_or_else(|| PipelineError::Data(format!("{key}[{i}]: no flight {}", iv.flight)))?;
        let data = f.io_data(virtual_inputs)?;
        let ti = TimeInterval::new(iv.from, iv.to).ctx(|| format!("{key}[{i}]"))?;
        if let Some(span) = Segment::all(ti).beyond_samples(&data) {
            return Err(PipelineError::Data(format!(
                "{key}[{i}]: flight {} {}..{} s reaches beyond the flight's samples ({}..{} s); \
                 shorten the interval or give a longer flight",
                iv.flight, iv.from, iv.to, span.first, span.last
            )));
        }
        parts.push(
            data.select(&[ti])
                .ctx(|| format!("{key}[{i}]: flight {} {}..{} s", iv.flight, iv.from, iv.to))?,
        );
    }
    IoData::merge(&parts).ctx(|| key.to_string())
}

/// Stage 1's result: the four flights in the order of
/// [`Experiment::ALL`].
#[derive(Clone, Debug)]
pub struct Experiments {
    /// Flights no. 1 to 4.
    pub flights: Vec<Flight>,
    /// Whether they were simulated (else given).
    pub simulated: bool,
}

impl Experiments {
    /// The flight of experiment number `k` (1 to 4).
    ///
    /// # Errors
    /// [`PipelineError::Data`] when there is none; `key` names the setting.
    pub fn flight(&self, k: u8, key: &str) -> Result<&Flight> {
        self.flights
            .iter()
            .find(|f| f.experiment.number() == k)
            .ok_or_else(|| PipelineError::Data(format!("{key} = {k}: no such flight")))
    }
}

/// Stage 1: simulates the four flights, or checks the given ones (one per
/// experiment, in the order of [`Experiment::ALL`], at least two samples).
///
/// # Errors
/// The simulator's errors; [`PipelineError::Data`] for a missing flight.
pub fn run(cfg: &Config, given: Option<Vec<Flight>>) -> Result<Experiments> {
    match given {
        None => Ok(Experiments {
            flights: Experiment::ALL
                .iter()
                .map(|e| Flight::simulate(*e, &cfg.experiments))
                .collect::<Result<_>>()?,
            simulated: true,
        }),
        Some(flights) => {
            for (k, e) in Experiment::ALL.iter().enumerate() {
                let f = flights.get(k).ok_or_else(|| {
                    PipelineError::Data(format!(
                        "no log of experiment {} ({})",
                        e.number(),
                        e.name()
                    ))
                })?;
                if f.experiment != *e {
                    return Err(PipelineError::Data(format!(
                        "flight {}: expected experiment {} ({}), found {}",
                        k + 1,
                        e.number(),
                        e.name(),
                        f.experiment.number()
                    )));
                }
                if f.t.len() < 2 {
                    return Err(PipelineError::Data(format!(
                        "{}: fewer than two samples",
                        file_name(*e)
                    )));
                }
            }
            Ok(Experiments {
                flights,
                simulated: false,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An interval reaching beyond its flight's samples is refused with the
    /// key and the samples' span (selection alone would cut it silently);
    /// within half a sample period of the last sample it is taken.
    #[test]
    fn an_interval_beyond_the_flight_is_refused() {
        let cfg = ExperimentsConfig {
            seconds: 6.0,
            seed: 1,
            dt: 0.001,
        };
        let flights = vec![Flight::simulate(Experiment::Decoupled, &cfg).unwrap()];
        let last = *flights[0].t.last().unwrap();
        assert!((last - 5.98).abs() < 1e-9, "{last}");
        let iv = |to| Interval {
            flight: 2,
            from: 1.0,
            to,
        };
        let data = select(&flights, &[iv(5.99)], false, "est").unwrap();
        assert_eq!(data.experiments()[0].t.last(), Some(&last));
        let err = select(&flights, &[iv(3.0), iv(8.0)], false, "est")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("est[1]: flight 2 1..8 s reaches beyond"),
            "{err}"
        );
        assert!(err.contains("(0..5.98 s)"), "{err}");
    }
}
