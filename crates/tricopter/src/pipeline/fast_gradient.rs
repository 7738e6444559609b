//! Stage 7: fast-gradient certificates (sections 6.3, 7.6.2), each checked
//! at random parameters against the polished reference QP.

use super::config::{Config, PreconditionerChoice};
use super::error::{Context, PipelineError, Result};
use super::problems::{Problem, ProblemName, Problems};
use super::sample::{BoxSampler, qp_cost};
use kestrel_fgm::{BoxQp, Certificate, FgmDesign, FgmSettings, Preconditioner};
use kestrel_mpc::{QpSettings, ReferenceSolver};
use nalgebra::DVector;

/// Relative slack of the certificate check: `J(z_i) - J* <= eps + SLACK (1 + |J*|)`.
/// The reference optimum is the polished (active-set) solution, exact to
/// rounding, so the slack covers rounding only.
pub const CHECK_SLACK: f64 = 1e-9;

/// The kestrel-fgm preconditioner of the configuration's choice.
pub fn preconditioner(c: PreconditionerChoice) -> Preconditioner {
    match c {
        PreconditionerChoice::None => Preconditioner::None,
        PreconditionerChoice::Jacobi => Preconditioner::Jacobi,
        PreconditionerChoice::OptimalDiagonal => Preconditioner::OptimalDiagonal,
    }
}

/// Which tolerance a certificate is for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EpsSource {
    /// A value of `fgm.eps_table`.
    Table,
    /// The level that keeps every pulse within `fgm.pwm_error` us.
    PwmError(f64),
}

/// One certificate and its check.
#[derive(Clone, Debug, PartialEq)]
pub struct CertificateCheck {
    /// The tolerance `eps` on `J(z_i) - J*`.
    pub eps: f64,
    /// Where it comes from.
    pub source: EpsSource,
    /// The certified iteration count.
    pub certificate: Certificate,
    /// Largest `J(z_i) - J*` over the random parameters.
    pub max_gap: f64,
    /// Whether `max_gap <= eps` (with [`CHECK_SLACK`]).
    pub holds: bool,
}

/// The fast gradient method on one problem.
#[derive(Clone, Debug)]
pub struct FgmProblem {
    /// Which problem.
    pub name: ProblemName,
    /// The design (preconditioned).
    pub design: FgmDesign,
    /// Certified iterations for `eps = 1e2` without preconditioning.
    pub iterations_unscaled: usize,
    /// Certified iterations for `eps = 1e2` after preconditioning.
    pub iterations_scaled: usize,
    /// The `eps` of the PWM accuracy (0 when not positive).
    pub eps_pwm: f64,
    /// The certificates of the table, then the PWM one.
    pub certificates: Vec<CertificateCheck>,
    /// The certificate the solvers run with (the PWM one, or the tightest
    /// of the table).
    pub pwm_certificate: Certificate,
    /// Random parameters per check.
    pub check_points: usize,
    /// Parameters at which the reference QP's polish did not verify (its
    /// optimum is then clarabel's own, to about `1e-9`).
    pub unpolished: usize,
}

/// Stage 7's result.
#[derive(Clone, Debug)]
pub struct FastGradient {
    /// The thesis-sized problem.
    pub thesis: FgmProblem,
    /// The larger problem.
    pub larger: FgmProblem,
    /// Whether every certificate holds.
    pub all_hold: bool,
}

impl FastGradient {
    /// Both, thesis-sized first.
    pub fn list(&self) -> [&FgmProblem; 2] {
        [&self.thesis, &self.larger]
    }
}

fn one(cfg: &Config, problem: &Problem) -> Result<FgmProblem> {
    let name = problem.name.as_str();
    let mpqp = &problem.mpqp;
    let qp = BoxQp::from_mpqp(mpqp).ctx(|| format!("the {name} problem as a box QP"))?;
    let d = FgmDesign::new(
        qp.clone(),
        FgmSettings {
            preconditioner: preconditioner(cfg.fgm.preconditioner),
            ..FgmSettings::default()
        },
    )
    .ctx(|| format!("the {name} problem's fast gradient design"))?;
    let plain = FgmDesign::new(
        qp,
        FgmSettings {
            preconditioner: Preconditioner::None,
            ..FgmSettings::default()
        },
    )
    .ctx(|| format!("the {name} problem's unscaled fast gradient design"))?;
    let certify = |d: &FgmDesign, eps: f64| {
        d.certify(eps)
            .ctx(|| format!("certifying the {name} problem at eps {eps}"))
    };
    let pc = &d.preconditioning;
    let eps_pwm = kestrel_fgm::eps_for_input_error(pc.before.mu, cfg.fgm.pwm_error);
    let mut eps_list: Vec<(f64, EpsSource)> = cfg
        .fgm
        .eps_table
        .iter()
        .map(|e| (*e, EpsSource::Table))
        .collect();
    if eps_pwm > 0.0 {
        eps_list.push((eps_pwm, EpsSource::PwmError(cfg.fgm.pwm_error)));
    }
    let certs: Vec<Certificate> = eps_list
        .iter()
        .map(|(e, _)| certify(&d, *e))
        .collect::<Result<_>>()?;
    // Every certificate at random theta against the polished reference.
    let mut ref_qp =
        ReferenceSolver::new(mpqp, QpSettings::default()).ctx(|| "the reference QP".into())?;
    let mut rng = BoxSampler::new(0xF6 + mpqp.n() as u64);
    let mut worst = vec![f64::NEG_INFINITY; certs.len()];
    let mut unpolished = 0;
    for _ in 0..cfg.fgm.check_points {
        let th = rng.theta(mpqp);
        let q = ref_qp.solve(&th).ctx(|| "the reference QP".into())?;
        if !q.polished {
            unpolished += 1;
        }
        let jstar = qp_cost(mpqp, &q.z, &th);
        for (c, w) in certs.iter().zip(worst.iter_mut()) {
            let z = d
                .solve(c, th.as_slice(), None, c.iterations)
                .ctx(|| format!("the fast gradient method on the {name} problem"))?;
            let j = qp_cost(mpqp, &DVector::from_vec(z), &th);
            *w = w.max(j - jstar);
        }
    }
    let certificates = eps_list
        .iter()
        .zip(&certs)
        .zip(&worst)
        .map(|(((eps, source), c), w)| CertificateCheck {
            eps: *eps,
            source: *source,
            certificate: c.clone(),
            max_gap: *w,
            holds: *w <= *eps + CHECK_SLACK * (1.0 + w.abs()),
        })
        .collect();
    let pwm_certificate = if eps_pwm > 0.0 {
        certs
            .last()
            .cloned()
            .ok_or_else(|| PipelineError::Data("no certificate".into()))?
    } else {
        certify(
            &d,
            cfg.fgm
                .eps_table
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
        )?
    };
    Ok(FgmProblem {
        name: problem.name,
        iterations_unscaled: certify(&plain, 1e2)?.iterations,
        iterations_scaled: certify(&d, 1e2)?.iterations,
        design: d,
        eps_pwm,
        certificates,
        pwm_certificate,
        check_points: cfg.fgm.check_points,
        unpolished,
    })
}

/// Stage 7.
///
/// # Errors
/// kestrel-fgm's and the reference QP's errors.
pub fn run(cfg: &Config, pr: &Problems, progress: &mut dyn FnMut(&str)) -> Result<FastGradient> {
    progress("7. fast gradient: thesis");
    let thesis = one(cfg, &pr.thesis)?;
    progress("7. fast gradient: larger");
    let larger = one(cfg, &pr.larger)?;
    let all_hold = [&thesis, &larger]
        .iter()
        .all(|p| p.certificates.iter().all(|c| c.holds));
    Ok(FastGradient {
        thesis,
        larger,
        all_hold,
    })
}
