//! Flight logs (Betaflight blackbox, Crazyflie uSD, PX4 ULog) as
//! identification data: the glue between `kestrel-logs` and
//! `kestrel_sysid::IoData`, for `kestrel identify --data LOG`.

use anyhow::Context;
use kestrel_logs::{ImportSettings, Imported, LogFormat, SegmentChoice, SignalSpec};
use kestrel_sysid::{Experiment, IoData};
use nalgebra::DMatrix;
use std::io::Read;
use std::path::Path;

/// True when the file at `path` starts with the magic bytes of a flight
/// log kestrel-logs reads (anything else is read as CSV).
pub fn is_flight_log(path: &Path) -> bool {
    let mut head = [0u8; 32];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .unwrap_or(0);
    LogFormat::detect(&head[..n]).is_some()
}

/// Reads the flight log at `path` (format from its magic bytes), takes
/// `inputs` and `outputs` (each `name=source`, a field name, or a name of
/// the format's default selection such as `motor0`, `m1`, `p`; empty: the
/// format's default), resamples them onto one grid at `rate_hz` by cell
/// means, and keeps `segment` (the airborne segments with the default
/// detection, or the whole log), each segment an experiment.
pub fn load_log_as_iodata(
    path: &Path,
    inputs: &[String],
    outputs: &[String],
    rate_hz: f64,
    segment: SegmentChoice,
) -> anyhow::Result<IoData> {
    let specs = |list: &[String]| -> anyhow::Result<Option<Vec<SignalSpec>>> {
        if list.is_empty() {
            return Ok(None);
        }
        Ok(Some(SignalSpec::parse_list(&list.join(","))?))
    };
    let settings = ImportSettings {
        rate_hz,
        inputs: specs(inputs)?,
        outputs: specs(outputs)?,
        segment,
        ..ImportSettings::default()
    };
    let imported = kestrel_logs::import_file(path, &settings)
        .with_context(|| format!("{}", path.display()))?;
    to_iodata(&imported).with_context(|| format!("{}", path.display()))
}

/// The imported grid data as an [`IoData`] (one experiment per segment).
pub fn to_iodata(imp: &Imported) -> anyhow::Result<IoData> {
    let nu = imp.n_inputs;
    let ny = imp.signals.len() - nu;
    let experiments = imp
        .experiments
        .iter()
        .map(|e| {
            let n = e.t.len();
            let u = DMatrix::from_fn(n, nu, |i, j| e.columns[j][i]);
            let y = DMatrix::from_fn(n, ny, |i, j| e.columns[nu + j][i]);
            Experiment {
                t: e.t.clone(),
                u,
                y,
            }
        })
        .collect();
    let names = |r: std::ops::Range<usize>| imp.signals[r].iter().map(|s| s.name.clone()).collect();
    Ok(IoData::from_experiments(
        1.0 / imp.rate_hz,
        names(0..nu),
        names(nu..imp.signals.len()),
        experiments,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn flight(file: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/flight")
            .join(file)
    }

    #[test]
    fn a_crazyflie_log_becomes_iodata() {
        let path = flight("crazyflie/log16");
        assert!(is_flight_log(&path));
        let data = load_log_as_iodata(&path, &[], &[], 50.0, SegmentChoice::Airborne).unwrap();
        assert_eq!(data.input_names(), ["m1", "m2", "m3", "m4"]);
        assert_eq!(data.output_names(), ["p", "q", "r"]);
        assert_eq!(data.experiments().len(), 2, "two flights");
        assert!((data.ts() - 0.02).abs() < 1e-15);
        // Named selection and the whole log: one experiment.
        let ins = ["m1".to_string(), "m=motor.m2".to_string()];
        let data =
            load_log_as_iodata(&path, &ins, &["gyro.z".into()], 100.0, SegmentChoice::All).unwrap();
        assert_eq!(data.input_names(), ["m1", "m"]);
        assert_eq!(data.output_names(), ["gyro.z"]);
        assert_eq!(data.experiments().len(), 1);
        assert!(data.n_samples() > 4600, "{}", data.n_samples());
        let err =
            load_log_as_iodata(&path, &["nope".into()], &[], 50.0, SegmentChoice::All).unwrap_err();
        assert!(format!("{err:#}").contains("nope"), "{err:#}");
        assert!(!is_flight_log(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("Cargo.toml")
                .as_path()
        ));
    }
}
