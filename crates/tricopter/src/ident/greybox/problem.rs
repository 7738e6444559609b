//! The search problem: free parameters, residuals and their exact
//! Jacobian from the forward sensitivity recursion.

use crate::ident::greybox::model::grey_box_model;
use crate::ident::greybox::spec::GreyBoxSpec;
use kestrel_sysid::{InnovationModel, IoData, Result, SysidError};
use kestrel_tricopter_model::GreyBoxParams;
use nalgebra::{DMatrix, DVector};

/// Data of one experiment as columns of time series (rows = samples).
pub(super) struct Series {
    pub(super) u: Vec<DVector<f64>>,
    pub(super) y: Vec<DVector<f64>>,
}

/// The search problem: which parameters move and how they map to a model.
pub(super) struct Problem<'a> {
    pub(super) spec: &'a GreyBoxSpec,
    pub(super) ts: f64,
    /// Indices (into the 8) of the free physical parameters of this stage.
    pub(super) phys: Vec<usize>,
    /// Whether the entries of `K` are parameters.
    pub(super) gain: Gain,
    /// Fixed physical parameters (log values are taken from theta for free ones).
    pub(super) g_fixed: GreyBoxParams,
    pub(super) nx: usize,
    pub(super) ny: usize,
    pub(super) series: Vec<Series>,
    /// Output scales `s_j`.
    pub(super) sy: Vec<f64>,
    /// Total residual count `N ny`.
    pub(super) m_total: usize,
    /// Log bounds of the free physical parameters.
    pub(super) lo: Vec<f64>,
    pub(super) hi: Vec<f64>,
}

/// How the innovation gain `K` is chosen in a search stage.
#[derive(Clone, Debug)]
pub(super) enum Gain {
    /// A fixed gain (zero: simulation).
    Fixed(DMatrix<f64>),
    /// Every entry a parameter.
    Free,
    /// `K = A C'`: the measured states are replaced by the measurement
    /// every step (`A - KC = A (I - C'C)`), the equation-error start.
    Reset,
}

/// Everything one evaluation gives.
pub(super) struct Eval {
    pub(super) model: InnovationModel,
    /// Scaled residuals `r = e_j / (s_j sqrt(N ny))`, stacked by experiment, time, output.
    pub(super) r: DVector<f64>,
    /// `dr/dθ` (when asked for).
    pub(super) jac: Option<DMatrix<f64>>,
}

impl Problem<'_> {
    pub(super) fn n_params(&self) -> usize {
        self.phys.len()
            + if self.k_free() { self.nx * self.ny } else { 0 }
            + self.nx * self.series.len()
    }

    pub(super) fn k_free(&self) -> bool {
        matches!(self.gain, Gain::Free)
    }

    pub(super) fn off_k(&self) -> usize {
        self.phys.len()
    }

    pub(super) fn off_x0(&self) -> usize {
        self.off_k() + if self.k_free() { self.nx * self.ny } else { 0 }
    }

    pub(super) fn params_of(&self, theta: &DVector<f64>) -> GreyBoxParams {
        let mut v = self.g_fixed.to_array();
        for (k, &i) in self.phys.iter().enumerate() {
            v[i] = theta[k].exp();
        }
        GreyBoxParams::from_array(&v)
    }

    pub(super) fn model_of(&self, theta: &DVector<f64>) -> Result<InnovationModel> {
        let mut m = grey_box_model(&self.params_of(theta), self.spec, self.ts)?;
        m.k = match &self.gain {
            Gain::Free => DMatrix::from_fn(self.nx, self.ny, |i, j| {
                theta[self.off_k() + i * self.ny + j]
            }),
            Gain::Fixed(k) => k.clone(),
            Gain::Reset => &m.a * m.c.transpose(),
        };
        Ok(m)
    }

    pub(super) fn x0s_of(&self, theta: &DVector<f64>) -> Vec<DVector<f64>> {
        (0..self.series.len())
            .map(|e| self.x0_of(theta, e))
            .collect()
    }

    pub(super) fn x0_of(&self, theta: &DVector<f64>, e: usize) -> DVector<f64> {
        let o = self.off_x0() + e * self.nx;
        DVector::from_fn(self.nx, |i, _| theta[o + i])
    }

    /// `dA/dθ_k`, `dB/dθ_k` of the free physical parameters by central
    /// differences of the parametrisation in log scale.
    pub(super) fn model_derivatives(
        &self,
        theta: &DVector<f64>,
        at: &InnovationModel,
    ) -> Result<Vec<(DMatrix<f64>, DMatrix<f64>)>> {
        let h = self.spec.settings.derivative_step;
        let mut out = Vec::with_capacity(self.phys.len());
        for k in 0..self.phys.len() {
            let mut tp = theta.clone();
            let mut tm = theta.clone();
            tp[k] += h;
            tm[k] -= h;
            let mp = grey_box_model(&self.params_of(&tp), self.spec, self.ts);
            let mm = grey_box_model(&self.params_of(&tm), self.spec, self.ts);
            // One-sided at the edge of the valid set (e.g. the inertia
            // triangle inequality of Table 7.1, which holds with equality).
            out.push(match (mp, mm) {
                (Ok(p), Ok(m)) => ((p.a - m.a) / (2.0 * h), (p.b - m.b) / (2.0 * h)),
                (Ok(p), Err(_)) => ((p.a - &at.a) / h, (p.b - &at.b) / h),
                (Err(_), Ok(m)) => ((&at.a - m.a) / h, (&at.b - m.b) / h),
                (Err(e), Err(_)) => return Err(e),
            });
        }
        Ok(out)
    }

    pub(super) fn evaluate(&self, theta: &DVector<f64>, with_jac: bool) -> Result<Eval> {
        let model = self.model_of(theta)?;
        let np = self.n_params();
        let (nx, ny) = (self.nx, self.ny);
        let abar = &model.a - &model.k * &model.c;
        let derivs = if with_jac {
            self.model_derivatives(theta, &model)?
        } else {
            Vec::new()
        };
        let norm = (self.m_total as f64).sqrt();
        let mut r = DVector::zeros(self.m_total);
        let mut jac = with_jac.then(|| DMatrix::zeros(self.m_total, np));
        let mut row = 0;
        for (ei, s) in self.series.iter().enumerate() {
            let mut x = self.x0_of(theta, ei);
            // Sensitivities dx/dθ, nx x np.
            let mut sens = DMatrix::<f64>::zeros(if with_jac { nx } else { 0 }, np);
            if with_jac {
                let o = self.off_x0() + ei * nx;
                for i in 0..nx {
                    sens[(i, o + i)] = 1.0;
                }
            }
            for (u, y) in s.u.iter().zip(&s.y) {
                let e = y - &model.c * &x - &model.d * u;
                for j in 0..ny {
                    r[row + j] = e[j] / (self.sy[j] * norm);
                }
                if let Some(jm) = jac.as_mut() {
                    let de = -(&model.c * &sens);
                    for j in 0..ny {
                        let sc = 1.0 / (self.sy[j] * norm);
                        for p in 0..np {
                            jm[(row + j, p)] = de[(j, p)] * sc;
                        }
                    }
                    let mut next = &abar * &sens;
                    for (k, (da, db)) in derivs.iter().enumerate() {
                        let mut col = da * &x + db * u;
                        if matches!(self.gain, Gain::Reset) {
                            // dK/dθ e with K = A C'.
                            col += da * (model.c.transpose() * &e);
                        }
                        for i in 0..nx {
                            next[(i, k)] += col[i];
                        }
                    }
                    if self.k_free() {
                        for i in 0..nx {
                            for j in 0..ny {
                                next[(i, self.off_k() + i * ny + j)] += e[j];
                            }
                        }
                    }
                    sens = next;
                }
                x = &model.a * &x + &model.b * u + &model.k * &e;
                row += ny;
            }
        }
        if !r.iter().all(|v| v.is_finite()) {
            return Err(SysidError::Numerical(
                "non-finite prediction errors (the model diverges on the data)".into(),
            ));
        }
        Ok(Eval { model, r, jac })
    }
}

/// A stable start for a free gain: `K = A C'` (measured states reset to
/// the measurement, the predictor's poles are the actuators') plus, for
/// the disturbance states (the last `ny`, unobserved by `C`), a gain
/// that puts their predictor poles near 0.8.
pub(super) fn start_gain(m: &InnovationModel, disturbance: bool) -> DMatrix<f64> {
    let mut k = &m.a * m.c.transpose();
    let (nx, ny) = (m.nx(), m.ny());
    if disturbance {
        // d+ = d + K_d e with e ~ ts (d - d_hat): error pole 1 - 0.2.
        for j in 0..ny {
            k[(nx - ny + j, j)] = 0.2 / m.ts;
        }
    }
    k
}

pub(super) fn series_of(data: &IoData) -> Vec<Series> {
    data.experiments()
        .iter()
        .map(|e| Series {
            u: (0..e.len()).map(|t| e.u.row(t).transpose()).collect(),
            y: (0..e.len()).map(|t| e.y.row(t).transpose()).collect(),
        })
        .collect()
}

impl<'a> Problem<'a> {
    pub(super) fn new(
        spec: &'a GreyBoxSpec,
        data: &IoData,
        g: GreyBoxParams,
        nx: usize,
        ny: usize,
        series: Vec<Series>,
        sy: &DVector<f64>,
    ) -> Self {
        let (lo, hi) = (spec.lower.to_array(), spec.upper.to_array());
        let phys: Vec<usize> = (0..8).filter(|&i| spec.free[i]).collect();
        let lnb = |v: f64| if v > 0.0 { v.ln() } else { f64::NEG_INFINITY };
        Problem {
            spec,
            ts: data.ts(),
            lo: phys.iter().map(|&i| lnb(lo[i])).collect(),
            hi: phys.iter().map(|&i| lnb(hi[i])).collect(),
            phys,
            gain: Gain::Reset,
            g_fixed: g,
            nx,
            ny,
            series,
            sy: sy.iter().copied().collect(),
            m_total: data.n_samples() * ny,
        }
    }
}
