//! The workflow of the thesis's chapter 7 as typed stages, from the four
//! flights to the firmware tables, without file I/O: [`run`] takes a
//! [`Config`] and (optionally) the flights, and returns a
//! [`PipelineResult`] holding every stage's named result. `kestrel
//! pipeline` renders it as a report directory.
//!
//! The stages, each a module: [`experiments`] (1), [`sensor`] (2),
//! [`identification`] (3), [`kalman`] (4), [`problems`] (5), [`explicit`]
//! (6), [`fast_gradient`] (7), [`table_7_2`] (8), [`closed_loop`] (9),
//! [`firmware`] (10), [`differences`] (11). Stage 4 runs after stage 5: the
//! Kalman filter is designed on the MPC's estimator model (with the
//! offset-free MPC's disturbance states), and it is the filter the closed
//! loop flies (stage 9) and the firmware carries (stage 10).

pub mod closed_loop;
pub mod config;
pub mod differences;
pub mod error;
pub mod experiments;
pub mod explicit;
pub mod fast_gradient;
pub mod filter;
pub mod firmware;
pub mod identification;
pub mod kalman;
pub mod problems;
pub mod result;
pub mod sample;
pub mod sensor;
pub mod summary;
pub mod table_7_2;

pub use config::Config;
pub use error::PipelineError;
pub use experiments::Flight;
pub use result::{PipelineResult, Stage};
pub use summary::Summary;

use std::time::Instant;

/// What [`run_with`] reports while it works.
pub trait Progress {
    /// A stage starts.
    fn stage(&mut self, stage: Stage);
    /// A step inside a stage (e.g. `6. explicit MPC: larger`).
    fn step(&mut self, message: &str);
}

/// No progress reports.
impl Progress for () {
    fn stage(&mut self, _: Stage) {}
    fn step(&mut self, _: &str) {}
}

/// Runs the pipeline on `cfg` (checked first), simulating the flights
/// unless `flights` gives them (one per experiment, in the order of
/// `kestrel_tricopter_model::Experiment::ALL`).
///
/// # Errors
/// A bad configuration value (naming its key), unusable flights, or the
/// first library error of a stage, with what the stage was doing.
pub fn run(cfg: &Config, flights: Option<Vec<Flight>>) -> Result<PipelineResult, PipelineError> {
    run_with(cfg, flights, &mut ())
}

/// [`run`] with progress reports.
///
/// # Errors
/// As [`run`].
pub fn run_with(
    cfg: &Config,
    flights: Option<Vec<Flight>>,
    progress: &mut dyn Progress,
) -> Result<PipelineResult, PipelineError> {
    cfg.check()?;
    let mut seconds = Vec::new();
    let mut st = Stages {
        seconds: &mut seconds,
        progress,
    };
    let experiments = st.run(Stage::Experiments, |_| experiments::run(cfg, flights))?;
    let sensor = st.run(Stage::Sensor, |_| sensor::run(cfg, &experiments))?;
    let identification = st.run(Stage::Identification, |_| {
        identification::run(cfg, &experiments)
    })?;
    let problems = st.run(Stage::Problems, |_| problems::run(cfg, &identification))?;
    let kalman = st.run(Stage::Kalman, |_| {
        kalman::run(cfg, &experiments, &sensor, &problems)
    })?;
    let explicit = st.run(Stage::Explicit, |p| explicit::run(cfg, &problems, p))?;
    let fast_gradient = st.run(Stage::FastGradient, |p| {
        fast_gradient::run(cfg, &problems, p)
    })?;
    let table_7_2 = st.run(Stage::Table72, |_| {
        table_7_2::run(cfg, &problems, &explicit, &fast_gradient)
    })?;
    let closed_loop = st.run(Stage::ClosedLoop, |p| {
        closed_loop::run(cfg, &problems, &kalman, &explicit, &fast_gradient, p)
    })?;
    let firmware = st.run(Stage::Firmware, |_| {
        firmware::run(cfg, &problems, &kalman, &explicit, &fast_gradient)
    })?;
    let differences = st.run(Stage::Differences, |_| {
        Ok(differences::run(
            cfg,
            &sensor,
            &identification,
            &explicit,
            &fast_gradient,
            &table_7_2,
            &closed_loop,
        ))
    })?;
    seconds.sort_by_key(|(s, _)| *s);
    Ok(PipelineResult {
        config: cfg.clone(),
        experiments,
        sensor,
        identification,
        kalman,
        problems,
        explicit,
        fast_gradient,
        table_7_2,
        closed_loop,
        firmware,
        differences,
        seconds,
    })
}

/// Times the stages and passes on their progress.
struct Stages<'a> {
    seconds: &'a mut Vec<(Stage, f64)>,
    progress: &'a mut dyn Progress,
}

impl Stages<'_> {
    fn run<T>(
        &mut self,
        stage: Stage,
        f: impl FnOnce(&mut dyn FnMut(&str)) -> Result<T, PipelineError>,
    ) -> Result<T, PipelineError> {
        self.progress.stage(stage);
        let t0 = Instant::now();
        let progress = &mut *self.progress;
        let v = f(&mut |m: &str| progress.step(m))?;
        self.seconds.push((stage, t0.elapsed().as_secs_f64()));
        Ok(v)
    }
}

#[cfg(test)]
mod tests;
