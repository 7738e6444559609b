//! The pipeline's result: every stage's named result, and the stages.

use super::{
    closed_loop, config::Config, differences, experiments, explicit, fast_gradient, firmware,
    identification, kalman, problems, sensor, table_7_2,
};

/// A stage of the pipeline, numbered as the report's sections.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    /// 1.
    Experiments,
    /// 2.
    Sensor,
    /// 3.
    Identification,
    /// 4.
    Kalman,
    /// 5.
    Problems,
    /// 6.
    Explicit,
    /// 7.
    FastGradient,
    /// 8.
    Table72,
    /// 9.
    ClosedLoop,
    /// 10.
    Firmware,
    /// 11.
    Differences,
}

impl Stage {
    /// Every stage in the report's order.
    pub const ALL: [Stage; 11] = [
        Stage::Experiments,
        Stage::Sensor,
        Stage::Identification,
        Stage::Kalman,
        Stage::Problems,
        Stage::Explicit,
        Stage::FastGradient,
        Stage::Table72,
        Stage::ClosedLoop,
        Stage::Firmware,
        Stage::Differences,
    ];

    /// `1. experiments` ... `11. differences`.
    pub fn title(self) -> &'static str {
        match self {
            Stage::Experiments => "1. experiments",
            Stage::Sensor => "2. sensor",
            Stage::Identification => "3. identification",
            Stage::Kalman => "4. Kalman filter",
            Stage::Problems => "5. MPC problems",
            Stage::Explicit => "6. explicit MPC",
            Stage::FastGradient => "7. fast gradient",
            Stage::Table72 => "8. Table 7.2",
            Stage::ClosedLoop => "9. closed loop",
            Stage::Firmware => "10. firmware tables",
            Stage::Differences => "11. differences",
        }
    }
}

/// Every stage's result.
#[derive(Clone, Debug)]
pub struct PipelineResult {
    /// The configuration run (after `--quick`, if applied).
    pub config: Config,
    /// 1.
    pub experiments: experiments::Experiments,
    /// 2.
    pub sensor: sensor::SensorStats,
    /// 3.
    pub identification: identification::Identification,
    /// 4: the filter flown (9) and carried by the firmware (10).
    pub kalman: kalman::KalmanStage,
    /// 5.
    pub problems: problems::Problems,
    /// 6.
    pub explicit: explicit::Explicit,
    /// 7.
    pub fast_gradient: fast_gradient::FastGradient,
    /// 8.
    pub table_7_2: table_7_2::Table72,
    /// 9.
    pub closed_loop: closed_loop::ClosedLoop,
    /// 10.
    pub firmware: firmware::Firmware,
    /// 11.
    pub differences: differences::Differences,
    /// Wall-clock seconds of each stage, in the report's order.
    pub seconds: Vec<(Stage, f64)>,
}
