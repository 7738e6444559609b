//! Reading the four flight logs of section 7.1 (CSV in the simulator's
//! column layout) into kestrel-tricopter's [`Flight`]s.

use anyhow::{Context, bail};
pub use kestrel_tricopter::pipeline::experiments::{Flight, file_name};
use kestrel_tricopter_model::Experiment;
use std::path::Path;

/// Reads the logs of the four experiments from a directory
/// (`flight-1-hover.csv` ... `flight-4-ground.csv`).
pub fn read_dir(dir: &Path) -> anyhow::Result<Vec<Flight>> {
    Experiment::ALL
        .iter()
        .map(|e| read(*e, &dir.join(file_name(*e))))
        .collect()
}

/// Reads a CSV log with the simulator's columns (`t, pwm1, pwm2, pwm3,
/// servo, throttle, u_roll, u_pitch, u_yaw, p, q, r, airborne`, and
/// optionally `true_p, true_q, true_r`). Errors name the file, the row
/// and the column.
pub fn read(e: Experiment, path: &Path) -> anyhow::Result<Flight> {
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
        "t", "pwm1", "pwm2", "pwm3", "servo", "throttle", "u_roll", "u_pitch", "u_yaw", "p", "q",
        "r", "airborne",
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
                    format!(
                        "{name}: line {row}, column `{c}`: expected a finite number, found {text:?}"
                    )
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
