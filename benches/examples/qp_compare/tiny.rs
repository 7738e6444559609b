//! The problem TinyMPC can express, built so that the condensed QP every
//! other solver gets and TinyMPC's uncondensed ADMM have the same optimum.
//!
//! TinyMPC (0.0.8) takes `x+ = A x + B u`, diagonal stage weights `Q`
//! (states) and `R` (inputs), box bounds per step, no move blocking, and
//! its own terminal weight: the ADMM step's Riccati solution `Pinf` for
//! `Q + rho I`, `R + rho I`, which makes the QP it converges to weigh
//! `x_N` with `Pinf - rho I`. The tricopter problem weighs the outputs
//! `y = C x` with `Q1 = 2000 I`; `C' Q1 C` is not diagonal, so the states
//! are rotated onto its eigenvectors `T` (orthogonal): `x~ = T' x`,
//! `A~ = T' A T`, `B~ = T' B`, `Q~ = diag(eig(C' Q1 C))`, the same cost
//! and inputs. The kestrel side condenses that model (`C = I`,
//! `Q1 = Q~`, `Q2 = 0.01 I` as the tricopter problem, the input bounds of
//! the trim at the throttle parameter, no blocking) with the terminal
//! weight `Pinf - rho I`, `Pinf` computed here by TinyMPC's own recursion
//! (same start, same stopping rule). References are zero (TinyMPC's
//! terminal linear term is not the one of its QP for a non-zero state
//! reference), so every theta has its reference entries set to zero.

use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_mpc::{MpcProblem, MpcSettings, Terminal, Weight};
use kestrel_qp::parametric::QpBuffers;
use kestrel_tricopter::constants::{PULSE_WEIGHT, RATE_WEIGHT};
use kestrel_tricopter::tricopter_trim;
use nalgebra::DMatrix;
use std::fmt::Write as _;
use std::ops::Range;
use std::path::Path;

/// One sample set for the TinyMPC harness: its label (`cold` or `warm`),
/// the thetas, the condensed QP's data at each (its bounds are TinyMPC's
/// input bounds) and kestrel-qp's solutions.
pub type TinySet<'a> = (
    &'a str,
    &'a [Vec<f64>],
    &'a [QpBuffers<f64>],
    &'a [Vec<f64>],
);

/// The rotated tricopter model, its diagonal weights and the condensed
/// problem of the same QP.
pub struct TinyProblem {
    /// The condensed problem (no blocking) as every other solver gets it.
    pub mpqp: MpqpProblem,
    /// `A~`, `B~` of the rotated model.
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    /// Diagonal state and input weights.
    q: Vec<f64>,
    r: Vec<f64>,
    /// Horizon (inputs); TinyMPC's knot points are one more.
    horizon: usize,
    /// ADMM penalty.
    rho: f64,
    /// Where the state and the references sit in theta.
    state: Range<usize>,
    references: Range<usize>,
}

/// TinyMPC's Riccati recursion for its cache (tiny_api.cpp,
/// `tiny_precompute_and_set_cache`): from `P = rho I`, at most 1000 steps,
/// stopped when `K` moves by less than 1e-5 (max entry); returns `Pinf`.
fn tiny_pinf(a: &DMatrix<f64>, b: &DMatrix<f64>, q: &[f64], r: &[f64], rho: f64) -> DMatrix<f64> {
    let (nx, nu) = (a.nrows(), b.ncols());
    let q1 = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        nx,
        q.iter().map(|v| v + rho),
    ));
    let r1 = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        nu,
        r.iter().map(|v| v + rho),
    ));
    let mut p_next = DMatrix::identity(nx, nx) * rho;
    let mut k_next = DMatrix::zeros(nu, nx);
    let mut p = DMatrix::zeros(nx, nx);
    for _ in 0..1000 {
        let m = &r1 + b.transpose() * &p_next * b;
        let k = m.try_inverse().expect("R1 + B'PB invertible") * b.transpose() * &p_next * a;
        p = &q1 + a.transpose() * &p_next * (a - b * &k);
        if (&k - &k_next).amax() < 1e-5 {
            break;
        }
        k_next = k;
        p_next = p.clone();
    }
    p
}

/// The tricopter model of `models/tricopter-blackbox-5.json` at horizon
/// `horizon` without blocking, rotated for diagonal weights, with ADMM
/// penalty `rho`.
pub fn tiny_problem(model: &SsModel, horizon: usize, rho: f64) -> TinyProblem {
    let nx = model.nx();
    let cqc = model.c.transpose() * &model.c * RATE_WEIGHT;
    let eig = cqc.symmetric_eigen();
    let t = eig.eigenvectors;
    let floor = 1e-12 * eig.eigenvalues.amax();
    let q: Vec<f64> = eig
        .eigenvalues
        .iter()
        .map(|&v| if v > floor { v } else { 0.0 })
        .collect();
    let a = t.transpose() * &model.a * &t;
    let b = t.transpose() * &model.b;
    let r = vec![PULSE_WEIGHT; model.nu()];
    let pinf = tiny_pinf(&a, &b, &q, &r, rho);
    let terminal = &pinf - DMatrix::identity(nx, nx) * rho;
    let mut rotated = SsModel::new(
        model.ts,
        a.clone(),
        b.clone(),
        DMatrix::identity(nx, nx),
        DMatrix::zeros(nx, model.nu()),
    )
    .expect("rotated model");
    rotated.u0 = model.u0.clone();
    let trim = tricopter_trim(model).expect("trim");
    let settings = trim.constrain(MpcSettings {
        horizon,
        blocking: None,
        q1: Weight::Diagonal(q.clone()),
        q2: Weight::Scalar(PULSE_WEIGHT),
        terminal: Terminal::State(terminal),
        ..MpcSettings::default()
    });
    let problem = MpcProblem::build(&rotated, &settings).expect("TinyMPC problem");
    TinyProblem {
        state: problem.layout.state(),
        references: problem.layout.references(),
        mpqp: problem.to_mpqp(),
        a,
        b,
        q,
        r,
        horizon,
        rho,
    }
}

impl TinyProblem {
    /// Sets the reference entries of every theta to zero.
    pub fn zero_references(&self, thetas: &mut [Vec<f64>]) {
        for t in thetas {
            t[self.references.clone()].fill(0.0);
        }
    }

    /// Writes the TinyMPC harness's input: the model, the weights, the
    /// configs `(label, tolerance, max_iter)` and the sets `(label, theta,
    /// the condensed QP's bounds at theta, kestrel-qp's solution)`.
    pub fn write(
        &self,
        path: &Path,
        name: &str,
        configs: &[(&str, f64, usize)],
        sets: &[TinySet<'_>],
    ) {
        let mut out = String::new();
        let (nx, nu) = (self.a.nrows(), self.b.ncols());
        let _ = writeln!(out, "{name} {nx} {nu} {} {:e}", self.horizon + 1, self.rho);
        let line = |v: &mut dyn Iterator<Item = f64>, out: &mut String| {
            for x in v {
                let _ = write!(out, "{x:e} ");
            }
            out.push('\n');
        };
        line(&mut self.a.transpose().iter().copied(), &mut out);
        line(&mut self.b.transpose().iter().copied(), &mut out);
        line(&mut self.q.iter().copied(), &mut out);
        line(&mut self.r.iter().copied(), &mut out);
        let _ = writeln!(out, "{}", configs.len());
        for (label, tol, max_iter) in configs {
            let _ = writeln!(out, "{label} {tol:e} {max_iter}");
        }
        let _ = writeln!(out, "{}", sets.len());
        for (label, thetas, bufs, zs) in sets {
            let _ = writeln!(out, "{label} {}", thetas.len());
            for ((theta, buf), z) in thetas.iter().zip(bufs.iter()).zip(zs.iter()) {
                line(&mut theta[self.state.clone()].iter().copied(), &mut out);
                line(&mut buf.lb.iter().copied(), &mut out);
                line(&mut buf.ub.iter().copied(), &mut out);
                line(&mut z.iter().copied(), &mut out);
            }
        }
        std::fs::write(path, out).expect("write the TinyMPC input");
    }
}
