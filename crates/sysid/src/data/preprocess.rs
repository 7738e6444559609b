//! Preprocessing: interval selection, splitting, offsets and trends,
//! input maps, low-pass filtering, excitation checks and scaling.

use super::{Experiment, IoData, Offsets, SignalSelection, TimeInterval};
use crate::error::{Result, SysidError};
use crate::filter::Butterworth;
use nalgebra::{DMatrix, DVector};

impl IoData {
    /// Selects time intervals: every part of every experiment whose time
    /// lies in an interval becomes its own experiment of the result (like
    /// picking estimation and validation sets and merging them). Intervals
    /// that cover no sample are an error.
    pub fn select(&self, intervals: &[TimeInterval]) -> Result<IoData> {
        let mut out = Vec::new();
        for iv in intervals {
            let before = out.len();
            for e in &self.experiments {
                let idx: Vec<usize> = (0..e.len())
                    .filter(|&k| e.t[k] >= iv.start - 1e-9 && e.t[k] <= iv.end + 1e-9)
                    .collect();
                if let (Some(&a), Some(&b)) = (idx.first(), idx.last()) {
                    out.push(Experiment {
                        t: e.t[a..=b].to_vec(),
                        u: e.u.rows(a, b - a + 1).into_owned(),
                        y: e.y.rows(a, b - a + 1).into_owned(),
                    });
                }
            }
            if out.len() == before {
                return Err(SysidError::invalid(format!(
                    "interval {}:{} contains no sample",
                    iv.start, iv.end
                )));
            }
        }
        IoData::from_experiments(
            self.ts,
            self.input_names.clone(),
            self.output_names.clone(),
            out,
        )
    }

    /// Splits every experiment at the sample fraction `frac` (0..1) into
    /// an estimation part and a validation part.
    pub fn split(&self, frac: f64) -> Result<(IoData, IoData)> {
        if !(frac > 0.0 && frac < 1.0) {
            return Err(SysidError::invalid(format!(
                "split fraction must lie in (0, 1), found {frac}"
            )));
        }
        let mut a = Vec::new();
        let mut b = Vec::new();
        for e in &self.experiments {
            let n = e.len();
            let k = ((n as f64) * frac).round() as usize;
            if k == 0 || k >= n {
                return Err(SysidError::TooFewSamples {
                    what: "a split".into(),
                    needed: 2,
                    found: n,
                });
            }
            a.push(Experiment {
                t: e.t[..k].to_vec(),
                u: e.u.rows(0, k).into_owned(),
                y: e.y.rows(0, k).into_owned(),
            });
            b.push(Experiment {
                t: e.t[k..].to_vec(),
                u: e.u.rows(k, n - k).into_owned(),
                y: e.y.rows(k, n - k).into_owned(),
            });
        }
        let mk = |x| {
            IoData::from_experiments(
                self.ts,
                self.input_names.clone(),
                self.output_names.clone(),
                x,
            )
        };
        Ok((mk(a)?, mk(b)?))
    }

    /// Means of inputs and outputs over all samples of all experiments.
    pub fn means(&self) -> Offsets {
        let n = self.n_samples() as f64;
        let mut u0 = DVector::zeros(self.nu());
        let mut y0 = DVector::zeros(self.ny());
        for e in &self.experiments {
            for j in 0..self.nu() {
                u0[j] += e.u.column(j).sum() / n;
            }
            for j in 0..self.ny() {
                y0[j] += e.y.column(j).sum() / n;
            }
        }
        Offsets { u0, y0 }
    }

    /// Subtracts a known operating point: `u - u0`, `y - y0` (the
    /// linearisation point, the gyro bias).
    pub fn subtract(&self, offsets: &Offsets) -> Result<IoData> {
        if offsets.u0.len() != self.nu() {
            return Err(SysidError::dim("u0", self.nu(), offsets.u0.len()));
        }
        if offsets.y0.len() != self.ny() {
            return Err(SysidError::dim("y0", self.ny(), offsets.y0.len()));
        }
        if offsets
            .u0
            .iter()
            .chain(offsets.y0.iter())
            .any(|v| !v.is_finite())
        {
            return Err(SysidError::invalid("offsets must be finite"));
        }
        let mut out = self.clone();
        for e in &mut out.experiments {
            for mut r in e.u.row_iter_mut() {
                r -= offsets.u0.transpose();
            }
            for mut r in e.y.row_iter_mut() {
                r -= offsets.y0.transpose();
            }
        }
        Ok(out)
    }

    /// Removes the common mean of every signal (one operating point for all
    /// experiments) and returns it, to be stored as `u0`/`y0`.
    pub fn remove_means(&self) -> Result<(IoData, Offsets)> {
        let o = self.means();
        Ok((self.subtract(&o)?, o))
    }

    /// Removes a least-squares straight line from every signal of every
    /// experiment separately (MATLAB's `detrend`).
    pub fn detrend(&self) -> IoData {
        let mut out = self.clone();
        for e in &mut out.experiments {
            let n = e.len();
            let tm = (n as f64 - 1.0) / 2.0;
            let stt: f64 = (0..n).map(|k| (k as f64 - tm).powi(2)).sum();
            for m in [&mut e.u, &mut e.y] {
                for mut col in m.column_iter_mut() {
                    let mean = col.sum() / n as f64;
                    let slope = if stt > 0.0 {
                        col.iter()
                            .enumerate()
                            .map(|(k, v)| (k as f64 - tm) * (v - mean))
                            .sum::<f64>()
                            / stt
                    } else {
                        0.0
                    };
                    for (k, v) in col.iter_mut().enumerate() {
                        *v -= mean + slope * (k as f64 - tm);
                    }
                }
            }
        }
        out
    }

    /// Replaces the inputs by `M u` (`M` is `nv x nu`), e.g. the virtual
    /// inputs of the thesis (3.28) computed from the motor signals.
    pub fn map_inputs(&self, m: &DMatrix<f64>, names: Vec<String>) -> Result<IoData> {
        if m.ncols() != self.nu() {
            return Err(SysidError::dim("input map columns", self.nu(), m.ncols()));
        }
        if names.len() != m.nrows() {
            return Err(SysidError::dim("input map names", m.nrows(), names.len()));
        }
        let exps = self
            .experiments
            .iter()
            .map(|e| Experiment {
                t: e.t.clone(),
                u: &e.u * m.transpose(),
                y: e.y.clone(),
            })
            .collect();
        IoData::from_experiments(self.ts, names, self.output_names.clone(), exps)
    }

    /// Applies a zero-phase (forward-backward) low-pass filter to the
    /// selected signals of every experiment.
    pub fn lowpass(&self, filter: &Butterworth, which: SignalSelection) -> IoData {
        let mut out = self.clone();
        for e in &mut out.experiments {
            let mut targets: Vec<&mut DMatrix<f64>> = Vec::new();
            match which {
                SignalSelection::Outputs => targets.push(&mut e.y),
                SignalSelection::Inputs => targets.push(&mut e.u),
                SignalSelection::Both => {
                    targets.push(&mut e.u);
                    targets.push(&mut e.y);
                }
            }
            for m in targets {
                for mut col in m.column_iter_mut() {
                    let x: Vec<f64> = col.iter().copied().collect();
                    let f = filter.filtfilt(&x);
                    for (v, n) in col.iter_mut().zip(f) {
                        *v = n;
                    }
                }
            }
        }
        out
    }

    /// Standard deviations of inputs and outputs over all data (about the
    /// common mean).
    pub fn stds(&self) -> (DVector<f64>, DVector<f64>) {
        let o = self.means();
        let n = self.n_samples().max(1) as f64;
        let mut su = DVector::zeros(self.nu());
        let mut sy = DVector::zeros(self.ny());
        for e in &self.experiments {
            for j in 0..self.nu() {
                su[j] +=
                    e.u.column(j)
                        .iter()
                        .map(|v| (v - o.u0[j]).powi(2))
                        .sum::<f64>();
            }
            for j in 0..self.ny() {
                sy[j] +=
                    e.y.column(j)
                        .iter()
                        .map(|v| (v - o.y0[j]).powi(2))
                        .sum::<f64>();
            }
        }
        (
            su.map(|v: f64| (v / n).sqrt()),
            sy.map(|v: f64| (v / n).sqrt()),
        )
    }

    /// Checks that every input varies and every output varies; returns the
    /// standard deviations `(inputs, outputs)`.
    pub fn check_excitation(&self) -> Result<(DVector<f64>, DVector<f64>)> {
        let (su, sy) = self.stds();
        let o = self.means();
        for j in 0..self.nu() {
            if su[j].is_nan() || su[j] <= 1e-9 * (1.0 + o.u0[j].abs()) {
                return Err(SysidError::ConstantInput {
                    name: self.input_names[j].clone(),
                    std: su[j],
                });
            }
        }
        for j in 0..self.ny() {
            if sy[j].is_nan() || sy[j] <= 1e-12 * (1.0 + o.y0[j].abs()) {
                return Err(SysidError::ConstantOutput {
                    name: self.output_names[j].clone(),
                });
            }
        }
        Ok((su, sy))
    }

    /// Scales every input and output column by the given factors.
    pub(crate) fn scaled(&self, su: &DVector<f64>, sy: &DVector<f64>) -> IoData {
        let mut out = self.clone();
        for e in &mut out.experiments {
            for (j, mut c) in e.u.column_iter_mut().enumerate() {
                c *= su[j];
            }
            for (j, mut c) in e.y.column_iter_mut().enumerate() {
                c *= sy[j];
            }
        }
        out
    }
}
