//! Stage 8: Table 7.2 (section 7.7.2): the reference QP, the explicit law,
//! the dual active-set solver and the fast gradient method at one
//! parameter of the thesis-sized problem, with host times.

use super::config::Config;
use super::error::{Context, PipelineError, Result};
use super::explicit::Explicit;
use super::fast_gradient::FastGradient;
use super::problems::Problems;
use super::sample::qp_cost;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::ExplicitSolver;
use kestrel_mpc::{ParametricQpSolver, QpSettings, ReferenceSolver};
use kestrel_qp::Start;
use kestrel_qp::parametric::ParametricQp;
use nalgebra::DVector;
use std::time::Instant;

/// Solves per host-time measurement.
pub const REPETITIONS: usize = 200;

/// The solver of a row.
#[derive(Clone, Debug, PartialEq)]
pub enum Solver {
    /// The reference QP (clarabel, polished).
    Qp,
    /// The explicit law.
    Explicit,
    /// kestrel-qp's dual active-set solver from a cold start (exact).
    ActiveSet {
        /// Active-set changes of the solve.
        iterations: usize,
    },
    /// The fast gradient method with a fixed iteration count.
    FgmFixed(usize),
    /// The fast gradient method with the count certified for `eps`
    /// (`pwm`: the PWM-accuracy level).
    FgmCertified {
        /// Certified iterations.
        iterations: usize,
        /// The tolerance.
        eps: f64,
        /// Whether it is the PWM-accuracy level.
        pwm: bool,
    },
}

/// One row of Table 7.2.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The solver.
    pub solver: Solver,
    /// The whole `z`.
    pub z: Vec<f64>,
    /// `J(z, theta)`, the QP objective.
    pub cost: f64,
    /// `J - J*`.
    pub gap: f64,
    /// Largest difference of the first move from the QP's (us).
    pub first_move_error: f64,
    /// Mean host time per solve (s).
    pub host_seconds: f64,
}

/// Stage 8's result.
#[derive(Clone, Debug)]
pub struct Table72 {
    /// The parameter.
    pub theta: DVector<f64>,
    /// Inputs of the first move.
    pub nu: usize,
    /// The optimum `J*`.
    pub j_star: f64,
    /// The QP row, the explicit row, the active-set row, the fast
    /// gradient rows.
    pub rows: Vec<Row>,
}

impl Table72 {
    /// The first move of a row.
    pub fn first_move<'a>(&self, row: &'a Row) -> &'a [f64] {
        &row.z[..self.nu]
    }
}

fn timed<T>(mut f: impl FnMut() -> Result<T>) -> Result<(T, f64)> {
    let t0 = Instant::now();
    let mut v = f()?;
    for _ in 1..REPETITIONS {
        v = f()?;
    }
    Ok((v, t0.elapsed().as_secs_f64() / REPETITIONS as f64))
}

/// The active-set solver's solution at `theta` from a cold start, its
/// iterations and its mean host time per solve (the solver set up once,
/// as on a target).
fn active_set(mpqp: &MpqpProblem, theta: &DVector<f64>) -> Result<(Vec<f64>, usize, f64)> {
    let ctx = || "the active-set solver".to_string();
    let par = ParametricQp::from_mpqp(mpqp).ctx(ctx)?;
    let (ns, ni) = par.workspace_len();
    let (mut scalars, mut indices) = (vec![0.0; ns], vec![0; ni]);
    let settings = kestrel_qp::QpSettings::default();
    let mut qp = par
        .solver::<f64>(settings, &mut scalars, &mut indices)
        .ctx(ctx)?;
    let mut buf = par.buffers::<f64>();
    par.fill(theta.as_slice(), &mut buf).ctx(ctx)?;
    let (info, secs) = timed(|| qp.solve(&buf.data(), Start::Cold).ctx(ctx))?;
    let mut z = vec![0.0; par.n()];
    qp.solution(&mut z).ctx(ctx)?;
    Ok((z, info.iterations, secs))
}

/// Stage 8.
///
/// # Errors
/// A singular `C`; the solvers' errors.
pub fn run(cfg: &Config, pr: &Problems, ex: &Explicit, fg: &FastGradient) -> Result<Table72> {
    let problem = &pr.thesis;
    let (p, mpqp) = (&problem.problem, &problem.mpqp);
    // With the disturbance states, C = [C 0]: x = [pinv(C) y; 0], d = 0.
    let x = pr
        .estimator_model
        .c
        .clone()
        .pseudo_inverse(1e-12)
        .map_err(|e| PipelineError::Data(format!("pseudo-inverse of C: {e}")))?
        * DVector::from_column_slice(&cfg.comparison.rates);
    let mut rr: Vec<f64> = cfg.comparison.reference.to_vec();
    rr.push(cfg.comparison.throttle);
    let theta = p
        .theta(x.as_slice(), &rr[..p.layout.n_law_reference()])
        .ctx(|| "Table 7.2's parameter".into())?;
    let nu = problem.nu();
    let mut qp =
        ReferenceSolver::new(mpqp, QpSettings::default()).ctx(|| "the reference QP".into())?;
    let (sol, t_qp) = timed(|| qp.solve(&theta).ctx(|| "the reference QP".into()))?;
    let jstar = qp_cost(mpqp, &sol.z, &theta);
    let row = |solver: Solver, z: Vec<f64>, secs: f64| -> Row {
        let zv = DVector::from_column_slice(&z);
        let cost = qp_cost(mpqp, &zv, &theta);
        Row {
            solver,
            first_move_error: (0..nu).map(|i| (z[i] - sol.z[i]).abs()).fold(0.0, f64::max),
            z,
            cost,
            gap: cost - jstar,
            host_seconds: secs,
        }
    };
    let mut rows = vec![row(Solver::Qp, sol.z.as_slice().to_vec(), t_qp)];
    let mut es = ExplicitSolver::new(ex.thesis.full.tables.clone());
    let mut z = vec![0.0; mpqp.n()];
    let ((), t_ex) = timed(|| {
        es.solve_into(theta.as_slice(), &mut z)
            .ctx(|| "the explicit law".into())
    })?;
    rows.push(row(Solver::Explicit, z, t_ex));
    let (za, iterations, t_as) = active_set(mpqp, &theta)?;
    rows.push(row(Solver::ActiveSet { iterations }, za, t_as));
    let f = &fg.thesis;
    let d = &f.design;
    let mut runs: Vec<Solver> = cfg
        .comparison
        .iterations
        .iter()
        .map(|k| Solver::FgmFixed(*k))
        .collect();
    for e in &cfg.fgm.eps_table {
        runs.push(Solver::FgmCertified {
            iterations: d
                .certify(*e)
                .ctx(|| format!("certifying eps {e}"))?
                .iterations,
            eps: *e,
            pwm: false,
        });
    }
    let cpwm = &f.pwm_certificate;
    runs.push(Solver::FgmCertified {
        iterations: cpwm.iterations,
        eps: cpwm.eps,
        pwm: true,
    });
    for solver in runs {
        let k = match solver {
            Solver::FgmFixed(k) | Solver::FgmCertified { iterations: k, .. } => k,
            Solver::Qp | Solver::Explicit | Solver::ActiveSet { .. } => continue,
        };
        let (zf, secs) = timed(|| {
            d.solve(cpwm, theta.as_slice(), None, k)
                .ctx(|| "the fast gradient method".into())
        })?;
        rows.push(row(solver, zf, secs));
    }
    Ok(Table72 {
        theta,
        nu,
        j_star: jstar,
        rows,
    })
}
