//! The candidates of the automatic structure choice and what it reports.

#[cfg(doc)]
use super::spec::AutoSelect;
use super::spec::{IdentifySpec, PemFocus, Start};
use crate::feedback::FeedbackTest;
use crate::n4sid::MatrixEstimate;
use crate::pem::Criterion;
use core::fmt;

/// One structure the choice tries: the spec's fields it sets.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Model order (`None`: suggested from the singular values).
    pub order: Option<usize>,
    /// The subspace method.
    pub start: Start,
    /// How N4SID estimates the system matrices.
    pub n4sid_matrices: MatrixEstimate,
    /// Estimate a feed-through `D`.
    pub feedthrough: bool,
    /// PEM focus.
    pub focus: PemFocus,
    /// Prediction horizon of the prediction-focus PEM stages.
    pub pem_horizon: usize,
    /// Largest spectral radius of `A` in the first PEM stage
    /// ([`PemSettings::max_radius_a`](crate::pem::PemSettings::max_radius_a));
    /// `None`: stable `A`. Above 1 only with the prediction focus: the
    /// predictor stays stable, the simulation of such a model diverges.
    pub max_radius_a: Option<f64>,
    /// N4SID block rows ([`IdentifySpec::horizon`]).
    pub horizon: Option<usize>,
    /// The PEM criterion ([`IdentifySpec::criterion`]).
    pub criterion: Criterion,
    /// The prediction steps of the criterion ([`IdentifySpec::pem_steps`]).
    pub pem_steps: Vec<usize>,
    /// PEM iterations of this candidate's fits, folds and final fit
    /// (they stop earlier on the tolerances); `None`: capped by the work
    /// estimates ([`AutoSelect::fold_work`], [`AutoSelect::final_work`]).
    pub iterations: Option<usize>,
}

impl Candidate {
    /// The candidate as the spec says it (every dimension as given).
    pub fn of_spec(spec: &IdentifySpec) -> Self {
        Candidate {
            order: spec.order,
            start: spec.start,
            n4sid_matrices: spec.n4sid_matrices,
            feedthrough: spec.feedthrough,
            focus: spec.focus,
            pem_horizon: spec.pem_horizon,
            max_radius_a: None,
            horizon: spec.horizon,
            criterion: spec.criterion,
            pem_steps: spec.pem_steps.clone(),
            iterations: None,
        }
    }

    /// `spec` with this candidate's fields (all but
    /// [`Candidate::max_radius_a`], which the fit takes beside the spec,
    /// and [`Candidate::iterations`], which sets
    /// [`IdentifySpec::max_iterations`] when given).
    pub fn apply(&self, spec: &IdentifySpec) -> IdentifySpec {
        IdentifySpec {
            order: self.order,
            start: self.start,
            n4sid_matrices: self.n4sid_matrices,
            feedthrough: self.feedthrough,
            focus: self.focus,
            pem_horizon: self.pem_horizon,
            horizon: self.horizon,
            criterion: self.criterion,
            pem_steps: self.pem_steps.clone(),
            max_iterations: self.iterations.unwrap_or(spec.max_iterations),
            ..spec.clone()
        }
    }

    /// A short description, e.g. `order 6, N4SID output-error, multi-step 1..5 then K`.
    pub fn label(&self) -> String {
        let order = self
            .order
            .map_or("order suggested".to_string(), |o| format!("order {o}"));
        let start = match (self.start, self.n4sid_matrices) {
            (Start::Pbsid, _) => "PBSID",
            (Start::N4sid, MatrixEstimate::OutputError) => "N4SID output-error",
            (Start::N4sid, MatrixEstimate::StateRegression) => "N4SID state-regression",
            (Start::Arx, _) => "ARX",
            (Start::Armax, _) => "ARMAX",
        };
        let start = match (self.start, self.horizon) {
            (Start::Arx | Start::Armax, l) => {
                format!("{start}({}) reduction", l.unwrap_or(super::spec::ARX_LAGS))
            }
            (_, Some(i)) => format!("{start} i = {i}"),
            (_, None) => start.to_string(),
        };
        let start = if self.feedthrough {
            format!("{start}, D")
        } else {
            start
        };
        let steps: Vec<String> = self.pem_steps.iter().map(|k| k.to_string()).collect();
        let focus = match self.focus {
            PemFocus::Prediction if self.pem_horizon == 1 => "1-step PEM".to_string(),
            PemFocus::Prediction if !steps.is_empty() => {
                format!("PEM steps {{{}}}", steps.join(", "))
            }
            PemFocus::Prediction => format!("PEM 1..{}-step", self.pem_horizon),
            PemFocus::Simulation => "simulation PEM".to_string(),
            PemFocus::SimulationThenNoise => "simulation PEM then K".to_string(),
            PemFocus::MultiStepThenNoise { horizon } => {
                format!("PEM 1..{horizon}-step then K ({}-step)", self.pem_horizon)
            }
        };
        let focus = match self.criterion {
            Criterion::Trace => focus,
            Criterion::Fit => format!("{focus}, fit criterion"),
            Criterion::Determinant => format!("{focus}, det criterion"),
        };
        let focus = match self.iterations {
            Some(n) => format!("{focus}, up to {n} iterations"),
            None => focus,
        };
        match self.max_radius_a {
            Some(r) => format!("{order}, {start}, {focus}, |eig A| <= {r}"),
            None => format!("{order}, {start}, {focus}"),
        }
    }
}

/// A candidate's cross-validation figures.
#[derive(Clone, Debug, PartialEq)]
pub struct CandidateScore {
    /// The candidate.
    pub candidate: Candidate,
    /// Mean over the folds of the mean fits in percent: simulation, then
    /// each table horizon (empty when a fold failed).
    pub fits: Vec<f64>,
    /// The score: per fold, the mean of the k-step fits and the
    /// simulation fit clipped at 0, minus the largest shortfall against
    /// that fold's baseline (the better of persistence and the best ARX
    /// of 2-10 lags); mean over the folds (minus infinity when a fold
    /// failed).
    pub score: f64,
    /// Why a fold failed.
    pub failed: Option<String>,
}

/// What the automatic structure choice chose and why.
#[derive(Clone, Debug, PartialEq)]
pub struct SelectionReport {
    /// Number of folds.
    pub folds: usize,
    /// The table horizons the scores use.
    pub horizons: Vec<usize>,
    /// The dimensions chosen.
    pub free: Vec<String>,
    /// The dimensions the spec fixed.
    pub fixed: Vec<String>,
    /// Every candidate tried, in the order tried.
    pub candidates: Vec<CandidateScore>,
    /// The choice (the best score).
    pub chosen: Candidate,
    /// Its score.
    pub score: f64,
    /// Wall time of the choice in seconds.
    pub seconds: f64,
    /// Whether the wall-clock safety stop ([`AutoSelect::time_budget`])
    /// fired before every planned candidate was fitted (the choice then
    /// depends on the machine's speed).
    pub budget_hit: bool,
    /// The work budget ([`AutoSelect::work_budget`]) and the part of it
    /// the planned candidates used.
    pub work: (f64, f64),
    /// The candidates left out because their estimated work exceeded
    /// what was left of the budget.
    pub skipped: Vec<Candidate>,
    /// The [`feedback_test`](crate::feedback_test) of the estimation
    /// data, or why it could not run (with [`AutoSelect::open_loop`]):
    /// with no feedback found the open-loop candidates (feed-through `D`,
    /// fit criterion over steps `{1, h}`) were added; `None`: not run.
    pub feedback: Option<core::result::Result<FeedbackTest, String>>,
    /// Why the open-loop candidates were or were not tried.
    pub open_loop: String,
    /// The folds' baseline per table horizon (mean fit over the folds,
    /// %): the better of persistence and the best ARX of 2-10 lags, each
    /// fold's own.
    pub reference: Vec<f64>,
}

impl fmt::Display for SelectionReport {
    /// The candidate table and the choice.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.feedback {
            Some(Ok(t)) => write!(f, "{t}")?,
            Some(Err(e)) => writeln!(f, "feedback test not run: {e}")?,
            None => {}
        }
        if !self.open_loop.is_empty() {
            writeln!(f, "{}", self.open_loop)?;
        }
        writeln!(
            f,
            "structure chosen by {}-fold blocked cross-validation inside the estimation data ({:.1} s{}; chosen: {}; fixed: {}):",
            self.folds,
            self.seconds,
            if self.budget_hit {
                ", WALL-CLOCK SAFETY STOP FIRED: the choice depends on the machine's load"
            } else {
                ""
            },
            if self.free.is_empty() {
                "nothing".to_string()
            } else {
                self.free.join(", ")
            },
            if self.fixed.is_empty() {
                "nothing".to_string()
            } else {
                self.fixed.join(", ")
            },
        )?;
        write!(
            f,
            "  {:<58}{:>10}",
            "candidate (mean fit over folds, %)", "sim"
        )?;
        for k in &self.horizons {
            write!(f, "{:>10}", format!("{k}-step"))?;
        }
        writeln!(f, "{:>10}", "score")?;
        for c in &self.candidates {
            let mark = if c.candidate == self.chosen { '*' } else { ' ' };
            write!(f, "{mark} {:<58}", c.candidate.label())?;
            match &c.failed {
                Some(e) => writeln!(f, "failed: {e}")?,
                None => {
                    for v in &c.fits {
                        write!(f, "{v:>10.2}")?;
                    }
                    writeln!(f, "{:>10.2}", c.score)?;
                }
            }
        }
        writeln!(
            f,
            "work planned {:.2e} of the budget {:.2e} (samples x parameters x states^2 x steps x iterations)",
            self.work.1, self.work.0
        )?;
        write!(
            f,
            "  {:<58}{:>10}",
            "baseline (best of persistence, ARX 2-10)", ""
        )?;
        for v in &self.reference {
            write!(f, "{v:>10.2}")?;
        }
        writeln!(f)?;
        for c in &self.skipped {
            writeln!(f, "  skipped (work budget): {}", c.label())?;
        }
        writeln!(
            f,
            "chosen: {} (score {:.2}: per fold, the mean of the k-step fits and the simulation fit clipped at 0 minus the largest shortfall against that fold's baseline; mean over the folds)",
            self.chosen.label(),
            self.score
        )
    }
}
