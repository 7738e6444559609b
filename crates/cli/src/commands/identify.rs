//! `kestrel identify`: a state-space model from a CSV flight log.

use crate::io;
use anyhow::{Context, bail};
use kestrel_sysid::{
    BalredSettings, Butterworth, CsvColumns, Focus, InnovationModel, IoData, N4sidSettings,
    Offsets, PemSettings, ReductionMethod, SignalSelection, TimeInterval, Weighting, balred, n4sid,
    pem, transmission_zeros, validate,
};
use nalgebra::{DMatrix, DVector};
use std::path::PathBuf;

/// Identification method.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Subspace identification only.
    N4sid,
    /// Prediction-error method started from N4SID.
    Pem,
}

/// N4SID weighting.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightingArg {
    /// MOESP.
    Moesp,
    /// Canonical variate analysis.
    Cva,
}

/// PEM criterion focus.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FocusArg {
    /// One-step prediction errors (estimates the Kalman gain K).
    Prediction,
    /// Simulation errors (K = 0).
    Simulation,
}

/// Identifies a discrete-time innovation-form model `x+ = Ax + B(u-u0) + Ke`,
/// `y - y0 = Cx + D(u-u0) + e` from a CSV log and writes it as
/// `kestrel.ss.v1` (removed offsets as `u0`/`y0`); prints the validation
/// table (simulation fit, k-step fits, persistence baseline, residual tests).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// CSV log with a header row.
    #[arg(long)]
    pub data: PathBuf,
    /// Input columns, comma separated (e.g. pwm1,pwm2,pwm3,servo).
    #[arg(long, value_delimiter = ',', required = true)]
    pub inputs: Vec<String>,
    /// Output columns, comma separated (e.g. p,q,r).
    #[arg(long, value_delimiter = ',', required = true)]
    pub outputs: Vec<String>,
    /// Estimation intervals `start:end,...` in seconds of the `t` column
    /// (row indices when there is none); default: all data.
    #[arg(long)]
    pub estimate: Option<String>,
    /// Validation intervals; default: the estimation data.
    #[arg(long)]
    pub validate: Option<String>,
    /// Model order; default: suggested from the singular values.
    #[arg(long)]
    pub order: Option<usize>,
    /// Reduce the identified model to this order by balanced truncation.
    #[arg(long)]
    pub reduce: Option<usize>,
    /// Keep the DC gain when reducing (singular perturbation).
    #[arg(long)]
    pub match_dc: bool,
    /// Identification method.
    #[arg(long, value_enum, default_value_t = Method::Pem)]
    pub method: Method,
    /// N4SID weighting.
    #[arg(long, value_enum, default_value_t = WeightingArg::Moesp)]
    pub weighting: WeightingArg,
    /// N4SID horizon (block rows); default chosen from the order.
    #[arg(long)]
    pub horizon: Option<usize>,
    /// PEM focus.
    #[arg(long, value_enum, default_value_t = FocusArg::Prediction)]
    pub focus: FocusArg,
    /// Estimate a feed-through matrix D.
    #[arg(long)]
    pub feedthrough: bool,
    /// Largest number of PEM iterations.
    #[arg(long, default_value_t = 30)]
    pub max_iterations: usize,
    /// Black-box virtual model: map the four inputs (motor 1, 2, 3, servo)
    /// through the mixer (3.28) to (U_r, U_p, U_y) with C_r = 1/sqrt(3),
    /// C_p = 2/3, C_y = 1.
    #[arg(long = "virtual")]
    pub virtual_inputs: bool,
    /// Known input operating point to remove (comma separated); default:
    /// the mean of the estimation data.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub u0: Option<Vec<f64>>,
    /// Known output offset (e.g. gyro bias) to remove; default: the mean of
    /// the estimation data.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub y0: Option<Vec<f64>>,
    /// Zero-phase Butterworth low-pass cut-off in rad/s applied to inputs
    /// and outputs (bilinear with pre-warping, forward-backward).
    #[arg(long)]
    pub lowpass: Option<f64>,
    /// Order of the low-pass filter.
    #[arg(long, default_value_t = 2)]
    pub lowpass_order: usize,
    /// Sample time when the file has no `t` column.
    #[arg(long)]
    pub ts: Option<f64>,
    /// Prediction horizons for the k-step fit table.
    #[arg(long, value_delimiter = ',', default_values_t = vec![1usize, 5])]
    pub horizons: Vec<usize>,
    /// Output model file (default: standard output, table on standard error).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn virtual_map() -> DMatrix<f64> {
    let cr = 1.0 / 3f64.sqrt();
    let cp = 2.0 / 3.0;
    DMatrix::from_row_slice(
        3,
        4,
        &[
            0.0,
            cr,
            -cr,
            0.0, //
            -cp,
            cp / 2.0,
            cp / 2.0,
            0.0, //
            0.0,
            0.0,
            0.0,
            1.0,
        ],
    )
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let src = args.data.display().to_string();
    let mut cols = CsvColumns::new(&[], &[]);
    cols.inputs = args.inputs.clone();
    cols.outputs = args.outputs.clone();
    cols.ts = args.ts;
    let mut data = IoData::read_csv(&args.data, &cols).with_context(|| format!("reading {src}"))?;
    if args.virtual_inputs {
        if data.nu() != 4 {
            bail!(
                "--virtual needs four inputs (motor 1, motor 2, motor 3, servo), found {}",
                data.nu()
            );
        }
        data = data.map_inputs(
            &virtual_map(),
            vec!["u_roll".into(), "u_pitch".into(), "u_yaw".into()],
        )?;
    }
    let parse = |s: &Option<String>, what: &str| -> anyhow::Result<Option<Vec<TimeInterval>>> {
        s.as_deref()
            .map(|t| TimeInterval::parse_list(t).with_context(|| format!("--{what}")))
            .transpose()
    };
    let est = match parse(&args.estimate, "estimate")? {
        Some(iv) => data.select(&iv).context("--estimate")?,
        None => data.clone(),
    };
    let val = match parse(&args.validate, "validate")? {
        Some(iv) => Some(data.select(&iv).context("--validate")?),
        None => None,
    };
    // Operating point: given, or the means of the estimation data.
    let means = est.means();
    let vec_arg = |v: &Option<Vec<f64>>,
                   n: usize,
                   default: &DVector<f64>,
                   what: &str|
     -> anyhow::Result<DVector<f64>> {
        match v {
            Some(v) if v.len() != n => bail!("--{what} needs {n} values, found {}", v.len()),
            Some(v) => Ok(DVector::from_vec(v.clone())),
            None => Ok(default.clone()),
        }
    };
    let u0 = if args.virtual_inputs && args.u0.is_some() {
        // A given u0 is in the raw inputs; map it too.
        let raw = vec_arg(&args.u0, 4, &DVector::zeros(4), "u0")?;
        virtual_map() * raw
    } else {
        vec_arg(&args.u0, est.nu(), &means.u0, "u0")?
    };
    let y0 = vec_arg(&args.y0, est.ny(), &means.y0, "y0")?;
    let offsets = Offsets { u0, y0 };
    let mut est = est.subtract(&offsets)?;
    let mut val = val.map(|v| v.subtract(&offsets)).transpose()?;
    if let Some(wc) = args.lowpass {
        let f = Butterworth::design(args.lowpass_order, wc, data.ts()).context("--lowpass")?;
        est = est.lowpass(&f, SignalSelection::Both);
        val = val.map(|v| v.lowpass(&f, SignalSelection::Both));
    }
    let n4 = N4sidSettings {
        order: args.order,
        max_order: args.order.unwrap_or(10).max(10),
        horizon: args.horizon,
        weighting: match args.weighting {
            WeightingArg::Moesp => Weighting::Moesp,
            WeightingArg::Cva => Weighting::Cva,
        },
        feedthrough: args.feedthrough,
        estimate_k: true,
    };
    let start = n4sid(&est, &n4).context("N4SID")?;
    let mut report = String::new();
    report.push_str(&format!(
        "data: {} estimation samples in {} experiment(s), ts = {} s; N4SID order {} (suggested {}), horizon {}\n",
        est.n_samples(),
        est.experiments().len(),
        est.ts(),
        start.order,
        start.suggested_order,
        start.horizon
    ));
    let mut model: InnovationModel = start.model.clone();
    if args.method == Method::Pem {
        let settings = PemSettings {
            focus: match args.focus {
                FocusArg::Prediction => Focus::Prediction,
                FocusArg::Simulation => Focus::Simulation,
            },
            feedthrough: args.feedthrough,
            max_iterations: args.max_iterations,
            ..Default::default()
        };
        let r = pem(&est, &start.model, &settings).context("PEM")?;
        report.push_str(&format!(
            "PEM: {} iterations, {} free parameters, cost {:.6} -> {:.6}, stopped: {:?}\n",
            r.iterations, r.free_parameters, r.initial_cost, r.cost, r.stop
        ));
        model = r.model;
    }
    if let Some(r) = args.reduce {
        let red = balred(
            &model,
            r,
            &BalredSettings {
                method: if args.match_dc {
                    ReductionMethod::MatchDc
                } else {
                    ReductionMethod::Truncate
                },
                include_noise: true,
            },
        )
        .context("--reduce")?;
        report.push_str(&format!(
            "balred {} -> {}: Hankel singular values {:.4?}, error bound {:.4}\n",
            model.nx(),
            r,
            red.hankel_singular_values,
            red.error_bound
        ));
        model = red.model;
    }
    match transmission_zeros(&model) {
        Ok(z) => {
            let nmp: Vec<String> = z
                .iter()
                .filter(|z| z.non_minimum_phase)
                .map(|z| format!("{:.4}{:+.4}i", z.z.re, z.z.im))
                .collect();
            report.push_str(&format!(
                "transmission zeros: {} ({} outside the unit circle{}{})\n",
                z.len(),
                nmp.len(),
                if nmp.is_empty() { "" } else { ": " },
                nmp.join(", ")
            ));
        }
        Err(e) => report.push_str(&format!("transmission zeros: not computed ({e})\n")),
    }
    let vdata = val.as_ref().unwrap_or(&est);
    report.push_str(if val.is_some() {
        "validation data:\n"
    } else {
        "no --validate intervals: table on the estimation data\n"
    });
    let rep = validate(&model, vdata, &args.horizons).context("validation")?;
    report.push_str(&rep.to_string());
    let ss = model.to_ss_model(
        Some(&offsets.u0),
        Some(&offsets.y0),
        Some(est.input_names()),
        Some(est.output_names()),
    )?;
    io::write_output(args.out.as_deref(), &ss.to_json_string())?;
    if args.out.is_some() {
        print!("{report}");
    } else {
        eprint!("{report}");
    }
    Ok(())
}
