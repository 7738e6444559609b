//! Runs a [`KalmanDesign`] as kestrel-kalman's const-dimension stationary
//! filter of the tricopter's 4 inputs and 3 outputs, whatever its number
//! of states (1 to [`MAX_STATES`]).

use super::error::{Context, PipelineError, Result};
use kestrel_kalman::{KalmanDesign, StationaryFilter};

/// Largest number of filter states the pipeline runs.
pub const MAX_STATES: usize = 16;

/// Something done with a filter of `NX` states.
pub trait WithFilter {
    /// What it returns.
    type Output;
    /// Does it.
    ///
    /// # Errors
    /// Whatever the work's errors are.
    fn run<const NX: usize>(self, filter: StationaryFilter<f64, NX, 4, 3>) -> Result<Self::Output>;
}

/// Builds the design's run-time filter and hands it to `work`.
///
/// # Errors
/// A design of 0 or more than [`MAX_STATES`] states, or not 4 inputs and
/// 3 outputs; kestrel-kalman's errors; `work`'s errors.
pub fn with_filter<W: WithFilter>(design: &KalmanDesign, work: W) -> Result<W::Output> {
    fn go<W: WithFilter, const NX: usize>(design: &KalmanDesign, work: W) -> Result<W::Output> {
        let f = design
            .filter::<f64, NX, 4, 3>()
            .ctx(|| "the stationary Kalman filter".into())?;
        work.run(f)
    }
    if (design.nu(), design.ny()) != (4, 3) {
        return Err(PipelineError::Data(format!(
            "the Kalman filter has {} inputs and {} outputs, the tricopter's has 4 and 3",
            design.nu(),
            design.ny()
        )));
    }
    match design.nx() {
        1 => go::<W, 1>(design, work),
        2 => go::<W, 2>(design, work),
        3 => go::<W, 3>(design, work),
        4 => go::<W, 4>(design, work),
        5 => go::<W, 5>(design, work),
        6 => go::<W, 6>(design, work),
        7 => go::<W, 7>(design, work),
        8 => go::<W, 8>(design, work),
        9 => go::<W, 9>(design, work),
        10 => go::<W, 10>(design, work),
        11 => go::<W, 11>(design, work),
        12 => go::<W, 12>(design, work),
        13 => go::<W, 13>(design, work),
        14 => go::<W, 14>(design, work),
        15 => go::<W, 15>(design, work),
        16 => go::<W, 16>(design, work),
        n => Err(PipelineError::Data(format!(
            "the pipeline's run-time filters support 1 to {MAX_STATES} states, found {n}"
        ))),
    }
}
