#![doc = include_str!("../README.md")]

mod betaflight;
mod crazyflie;
mod error;
mod import;
mod model;
mod number;
mod read;
mod resample;
mod segments;
mod select;
mod ulog;

pub use error::{LogError, Result};
pub use import::{
    Experiment, ImportSettings, Imported, LogSummary, SegmentChoice, SignalInfo, import,
    import_file,
};
pub use model::{Field, Issue, Log, LogFormat, ReadOptions, Topic, Unit};
pub use read::{read_bytes, read_file};
pub use resample::{Grid, Resampled, resample};
pub use segments::{AirborneSettings, Span};
pub use select::{DefaultSignals, Resolved, SignalSpec, default_signals, resolve};
