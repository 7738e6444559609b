//! The four flights of section 7.1: simulated by kestrel-tricopter-model,
//! or read from CSV logs in the simulator's column layout.

use anyhow::{Context, bail};
use kestrel_sysid::{Experiment as SysidExperiment, IoData, TimeInterval};
use kestrel_tricopter_model::{Experiment, SimSettings};
use nalgebra::DMatrix;
use std::path::Path;

use super::config::{Experiments, Interval};

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
    /// The CSV text of the log (written into the report).
    pub csv: Vec<u8>,
}

/// The file name of flight `k` in a report or a `--flights` directory.
pub fn file_name(e: Experiment) -> String {
    format!("flight-{}-{}.csv", e.number(), e.name())
}

impl Flight {
    /// Simulates experiment `e` with the configured length and seed.
    pub fn simulate(e: Experiment, cfg: &Experiments) -> anyhow::Result<Self> {
        let seed = cfg.seed + u64::from(e.number()) - 1;
        let mut settings = SimSettings::new(e, cfg.seconds, seed);
        settings.plant.dt = cfg.dt;
        let log = kestrel_tricopter_model::simulate(&settings)
            .with_context(|| format!("simulating experiment {} ({})", e.number(), e.name()))?;
        let csv = log.to_csv_bytes()?;
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

    /// Reads a CSV log with the simulator's columns (`t, pwm1, pwm2, pwm3,
    /// servo, throttle, u_roll, u_pitch, u_yaw, p, q, r, airborne`, and
    /// optionally `true_p, true_q, true_r`). Errors name the file, the row
    /// and the column.
    pub fn read(e: Experiment, path: &Path) -> anyhow::Result<Self> {
        let name = path.display().to_string();
        let bytes = std::fs::read(path).with_context(|| format!("reading {name}"))?;
        let mut rdr = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(bytes.as_slice());
        let headers: Vec<String> = rdr
            .headers()
            .with_context(|| format!("{name}: reading the header row"))?
            .iter()
            .map(str::to_string)
            .collect();
        let col = |c: &str| -> anyhow::Result<usize> {
            headers.iter().position(|h| h == c).with_context(|| {
                format!("{name}: no column `{c}` (a flight log needs t, pwm1, pwm2, pwm3, servo, throttle, u_roll, u_pitch, u_yaw, p, q, r, airborne)")
            })
        };
        let required = [
            "t", "pwm1", "pwm2", "pwm3", "servo", "throttle", "u_roll", "u_pitch", "u_yaw", "p",
            "q", "r", "airborne",
        ];
        let idx: Vec<usize> = required
            .iter()
            .map(|c| col(c))
            .collect::<anyhow::Result<_>>()?;
        let truth_idx: Option<Vec<usize>> = ["true_p", "true_q", "true_r"]
            .iter()
            .map(|c| headers.iter().position(|h| h == c))
            .collect();
        let mut f = Flight {
            experiment: e,
            t: vec![],
            pwm: vec![],
            throttle: vec![],
            virtual_input: vec![],
            gyro: vec![],
            truth: truth_idx.as_ref().map(|_| vec![]),
            airborne: vec![],
            true_offsets: None,
            csv: Vec::new(),
        };
        for (k, rec) in rdr.records().enumerate() {
            let row = k + 2; // the header is line 1
            let rec = rec.with_context(|| format!("{name}: line {row}"))?;
            let num = |j: usize, c: &str| -> anyhow::Result<f64> {
                let text = rec.get(j).unwrap_or("");
                text.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .with_context(|| {
                        format!("{name}: line {row}, column `{c}`: expected a finite number, found {text:?}")
                    })
            };
            let v: Vec<f64> = idx
                .iter()
                .zip(required)
                .map(|(&j, c)| num(j, c))
                .collect::<anyhow::Result<_>>()?;
            if let Some(last) = f.t.last()
                && v[0] <= *last
            {
                bail!(
                    "{name}: line {row}, column `t`: time {} does not increase (previous {last})",
                    v[0]
                );
            }
            f.t.push(v[0]);
            f.pwm.push([v[1], v[2], v[3], v[4]]);
            f.throttle.push(v[5]);
            f.virtual_input.push([v[6], v[7], v[8]]);
            f.gyro.push([v[9], v[10], v[11]]);
            f.airborne.push(v[12] != 0.0);
            if let (Some(ti), Some(tr)) = (&truth_idx, &mut f.truth) {
                tr.push([
                    num(ti[0], "true_p")?,
                    num(ti[1], "true_q")?,
                    num(ti[2], "true_r")?,
                ]);
            }
        }
        if f.t.len() < 2 {
            bail!("{name}: fewer than two samples");
        }
        f.csv = bytes;
        Ok(f)
    }

    /// Sample time (s).
    pub fn ts(&self) -> f64 {
        (self.t[self.t.len() - 1] - self.t[0]) / (self.t.len() - 1) as f64
    }

    /// The flight as an identification data set: inputs the four pulses
    /// (`virtual_inputs`: the three mixer inputs), outputs the gyro.
    pub fn io_data(&self, virtual_inputs: bool) -> anyhow::Result<IoData> {
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
        Ok(IoData::from_experiments(
            self.ts(),
            names,
            vec!["p".into(), "q".into(), "r".into()],
            vec![SysidExperiment {
                t: self.t.clone(),
                u,
                y,
            }],
        )?)
    }
}

/// The data set of the given intervals, each an experiment of its own
/// (MATLAB's `merge`), from flights 2 and 3.
pub fn select(
    flights: &[Flight],
    intervals: &[Interval],
    virtual_inputs: bool,
    key: &str,
) -> anyhow::Result<IoData> {
    let mut parts = Vec::new();
    for (i, iv) in intervals.iter().enumerate() {
        let f = flights
            .iter()
            .find(|f| f.experiment.number() == iv.flight)
            .with_context(|| format!("{key}[{i}]: no flight {}", iv.flight))?;
        let data = f.io_data(virtual_inputs)?;
        let ti = TimeInterval::new(iv.from, iv.to).with_context(|| format!("{key}[{i}]"))?;
        parts.push(data.select(&[ti]).with_context(|| {
            format!("{key}[{i}]: flight {} {}..{} s", iv.flight, iv.from, iv.to)
        })?);
    }
    IoData::merge(&parts).with_context(|| key.to_string())
}
