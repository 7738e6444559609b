//! `kestrel kalman`: stationary Kalman filter design (MATLAB's / python-control's `dlqe`).

use crate::io;
use anyhow::{Context, bail};
use kestrel_core::formats::SsModel;
use kestrel_core::formats::matrix_from_text;
use kestrel_kalman::{KalmanDesign, NoiseModel};
use nalgebra::{DMatrix, DVector};
use std::path::{Path, PathBuf};

/// Designs the stationary Kalman filter of a discrete `kestrel.ss.v1` model
/// for `x+ = A x + B (u - u0) + G w`, `y = C x + D (u - u0) + y0 + bias + v`,
/// `Cov(w) = Q`, `Cov(v) = R`, and writes `kestrel.kalman.v1`: the
/// measurement-update gain `M`, the predictor gain `L` (= A M), the
/// steady-state one-step prediction covariance `P`, and the model, noise
/// model and operating point the run-time filter needs.
#[derive(clap::Args, Debug)]
#[command(after_long_help = HELP)]
pub struct Args {
    /// Discrete model file (`kestrel.ss.v1`, `ts > 0`).
    #[arg(long)]
    pub model: PathBuf,
    /// Process noise covariance: a number `q` (meaning `q I`) or a JSON
    /// matrix file (an array of rows, or an object with key "Q").
    #[arg(
        long,
        allow_hyphen_values = true,
        required_unless_present = "innovations"
    )]
    pub q: Option<String>,
    /// Measurement noise covariance: a number `r` (meaning `r I`) or a JSON
    /// matrix file (an array of rows, or an object with key "R"). With
    /// `--innovations`: the innovation covariance (default the identity;
    /// it does not change the gain).
    #[arg(
        long,
        allow_hyphen_values = true,
        required_unless_present = "innovations"
    )]
    pub r: Option<String>,
    /// How the process noise enters the state (`nx x nw` JSON matrix file,
    /// an array of rows or an object with key "G"); default the identity.
    #[arg(long)]
    pub g: Option<PathBuf>,
    /// Cross-covariance `E[w v']` (`nw x ny` JSON matrix file, key "N").
    #[arg(long)]
    pub cross: Option<PathBuf>,
    /// The noise model of the model's own innovation gain `K` (an
    /// identified model, `kestrel identify`): `x+ = A x + B u + K e`,
    /// `y = C x + D u + e`, so `G = K` and `Q = R = N = Cov(e)` (`--r`).
    /// The filter is then the model's one-step predictor (`L = K`, `P = 0`,
    /// `M = 0`) when `A - K C` is stable.
    #[arg(long, conflicts_with_all = ["q", "g", "cross"])]
    pub innovations: bool,
    /// Known constant sensor bias, one number per output, comma separated
    /// (e.g. the gyro bias of thesis (7.5)); removed from every measurement.
    #[arg(long, allow_hyphen_values = true, value_delimiter = ',')]
    pub bias: Option<Vec<f64>>,
    /// Output file (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub replace: io::Replace,
}

/// The inputs and outputs, shown after the flags by `kestrel kalman --help`.
const HELP: &str = "\
Inputs:
  --model    a discrete kestrel.ss.v1 model (A, B, C, D, ts > 0; optional u0, y0):
             x+ = A x + B (u - u0) + G w,  y = C x + D (u - u0) + y0 + bias + v
  --q, --r   Cov(w) and Cov(v): a number v (meaning v I) or a JSON matrix file
  --g        how w enters the state (default: the identity); --cross: E[w v']
  --innovations  instead of --q, --g, --cross: the model's innovation gain K
             (kestrel identify writes it), e entering as w = v; --r is Cov(e)
  --bias     the constant sensor bias (e.g. the gyro bias from a ground segment)

Output (--out, or standard output): a kestrel.kalman.v1 file with the model,
the noise model, u0, y0, bias, and
  M   nx x ny  measurement-update gain (MATLAB dlqe's M): x_k|k = x_k|k-1 + M e_k
  L   nx x ny  predictor gain (python-control dlqe's L; = A M without --cross)
  P   nx x nx  steady-state covariance of the one-step prediction (dlqe's P)
  Z   nx x nx  covariance after the measurement update
  eigenvalues  of A - L C;  residual  relative residual of the Riccati equation
  multiply_adds  cost of one run-time step of the folded stationary filter
                 (2 nx ny + nx^2 + nx nu, + ny nu with D, + nx ny with --cross;
                 75 for 5 states, 4 inputs, 3 outputs)
A summary (states, spectral radius, residual, multiply-adds) goes to stderr.
Bad input (shapes, NaN, asymmetric or indefinite covariances, undetectable
or unstabilisable pairs) stops the command with a message naming the file
and the problem.";

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    args.replace.check(&[args.out.as_deref()])?;
    let model = SsModel::read(&args.model).with_context(|| format!("{}", args.model.display()))?;
    if model.ts <= 0.0 {
        bail!(
            "{}: the model is continuous-time (ts = {}); discretise it first with `kestrel c2d`",
            args.model.display(),
            model.ts
        );
    }
    let (nx, ny) = (model.nx(), model.ny());
    let g = args
        .g
        .as_deref()
        .map(|p| read_matrix(p, "G", Some(nx), None))
        .transpose()
        .context("--g")?;
    let nw = g.as_ref().map_or(nx, |g| g.ncols());
    let r = match &args.r {
        Some(r) => covariance(r, "R", ny).context("--r")?,
        None => DMatrix::identity(ny, ny),
    };
    let innovation_gain = match (args.innovations, &model.k) {
        (false, _) => None,
        (true, Some(k)) => Some(k.clone()),
        (true, None) => bail!(
            "--innovations: {} has no innovation gain K (kestrel identify writes one); give --q and --r instead",
            args.model.display()
        ),
    };
    let (g, q, cross) = match &innovation_gain {
        Some(k) => {
            let n = NoiseModel::innovations(k, &r);
            (n.g, n.q, n.cross)
        }
        None => {
            let Some(q) = args.q.as_deref() else {
                bail!("--q is needed (the process noise covariance), or --innovations");
            };
            let q = covariance(q, "Q", nw).context("--q")?;
            let cross = args
                .cross
                .as_deref()
                .map(|p| read_matrix(p, "N", Some(nw), Some(ny)))
                .transpose()
                .context("--cross")?;
            (g, q, cross)
        }
    };
    let bias = match args.bias {
        Some(b) => {
            if b.len() != ny {
                bail!(
                    "--bias: expected {ny} numbers (one per output), found {}",
                    b.len()
                );
            }
            if b.iter().any(|v| !v.is_finite()) {
                bail!("--bias: every entry must be finite");
            }
            Some(DVector::from_vec(b))
        }
        None => None,
    };
    let noise = NoiseModel {
        g,
        q,
        r,
        cross,
        bias,
    };
    let design = KalmanDesign::new(&model, &noise).with_context(|| {
        let mut what = format!("designing the filter for {}", args.model.display());
        if let Some(k) = &innovation_gain
            && let Ok(rho) = kestrel_core::eig::spectral_radius(&(&model.a - k * &model.c))
            && rho >= 1.0
        {
            what += &format!(
                " from its innovation gain: the model's predictor A - K C is not stable (spectral radius {rho:.4}), so K is no Kalman gain of its noise model; identify with a stable predictor or give --q and --r"
            );
        }
        what
    })?;
    if args.out.is_some() {
        let rho = design
            .filter
            .closed_loop_eigenvalues
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        eprintln!(
            "kalman: {nx} states, {ny} outputs; predictor spectral radius {rho:.4}, Riccati residual {:.1e}; stationary step {} multiply-adds",
            design.filter.residual,
            design.multiply_adds()
        );
    }
    if let Some(k) = &innovation_gain {
        innovations_note(k, &design);
    }
    io::write_output(args.out.as_deref(), &design.to_json_string())
}

/// Says whether the filter designed from the model's innovation gain is
/// that gain (it is whenever the design succeeds, `A - K C` being stable;
/// a difference would be a numerical failure, said as such).
fn innovations_note(k: &DMatrix<f64>, design: &KalmanDesign) {
    let diff = (&design.filter.l - k).amax();
    let scale = k.amax().max(f64::MIN_POSITIVE);
    if diff <= 1e-6 * scale {
        eprintln!(
            "kalman: the filter is the model's own predictor (L = K to {:.1e} relative)",
            diff / scale
        );
    } else {
        eprintln!(
            "warning: the filter's predictor gain differs from the model's K by {:.3e} relative (largest entry); the Riccati solution is not the model's predictor",
            diff / scale
        );
    }
}

/// A covariance given as a number (times the identity) or a matrix file.
fn covariance(arg: &str, key: &str, n: usize) -> anyhow::Result<DMatrix<f64>> {
    if let Ok(v) = arg.trim().parse::<f64>() {
        if !v.is_finite() || v < 0.0 {
            bail!("{key} = {arg}: must be a finite number >= 0 (meaning {key} = {arg} I)");
        }
        return Ok(DMatrix::identity(n, n) * v);
    }
    let path = Path::new(arg);
    if !path.exists() {
        bail!("\"{arg}\" is neither a number nor an existing JSON matrix file");
    }
    read_matrix(path, key, Some(n), Some(n))
}

/// Reads a JSON matrix file ([`matrix_from_text`]: a bare array of rows, or
/// an object holding `key`).
fn read_matrix(
    path: &Path,
    key: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> anyhow::Result<DMatrix<f64>> {
    let text = kestrel_core::formats::read_text(path)?;
    matrix_from_text(&text, key, rows, cols).with_context(|| format!("{}", path.display()))
}
