//! What a log is once read: topics (streams sharing one clock) of named
//! fields, each with its unit and, for commands, its range.

use std::fmt;

/// The first line of a Betaflight blackbox log.
pub(crate) const BETAFLIGHT_MAGIC: &[u8] = b"H Product:Blackbox";
/// The first bytes of a ULog file (`ULog` then 0x01 0x12 0x35).
pub(crate) const ULOG_MAGIC: &[u8] = &[0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35];
/// The first byte of a Crazyflie uSD log.
pub(crate) const CRAZYFLIE_MAGIC: u8 = 0xBC;

/// How to read a log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Keep what can be read from a damaged log instead of failing: a
    /// truncated or corrupt tail is dropped, a corrupt Betaflight frame is
    /// skipped up to the next intra frame, a CRC mismatch is noted; each
    /// becomes an [`Issue`] of the [`Log`]. Default `false`: the first
    /// damage is an error naming its byte offset.
    pub salvage: bool,
}

/// A supported log format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LogFormat {
    /// Betaflight (Cleanflight, INAV) blackbox, `.bbl`/`.bfl`.
    Betaflight,
    /// Crazyflie uSD-card binary log.
    Crazyflie,
    /// PX4 ULog, `.ulg`.
    Ulog,
}

impl LogFormat {
    /// The format whose magic bytes `bytes` starts with, if any.
    ///
    /// ```
    /// use kestrel_logs::LogFormat;
    /// assert_eq!(LogFormat::detect(b"H Product:Blackbox flight data recorder"), Some(LogFormat::Betaflight));
    /// assert_eq!(LogFormat::detect(&[0xBC, 2, 0]), Some(LogFormat::Crazyflie));
    /// assert_eq!(LogFormat::detect(b"ULog\x01\x12\x35\x01"), Some(LogFormat::Ulog));
    /// assert_eq!(LogFormat::detect(b"t,u,y\n"), None);
    /// ```
    pub fn detect(bytes: &[u8]) -> Option<LogFormat> {
        // A file shorter than the magic bytes but agreeing with them is a
        // truncated log of that format.
        let magic = |m: &[u8]| {
            let n = bytes.len().min(m.len());
            n >= 2 && bytes[..n] == m[..n]
        };
        if magic(BETAFLIGHT_MAGIC) {
            Some(LogFormat::Betaflight)
        } else if magic(ULOG_MAGIC) {
            Some(LogFormat::Ulog)
        } else if bytes.first() == Some(&CRAZYFLIE_MAGIC) {
            Some(LogFormat::Crazyflie)
        } else {
            None
        }
    }
}

impl fmt::Display for LogFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LogFormat::Betaflight => "Betaflight blackbox",
            LogFormat::Crazyflie => "Crazyflie uSD",
            LogFormat::Ulog => "PX4 ULog",
        })
    }
}

/// The unit of a field's values.
#[derive(Clone, Debug, PartialEq)]
pub enum Unit {
    /// Radians per second (every gyro, converted from the firmware's unit).
    RadPerSecond,
    /// Standard gravities (accelerometers).
    StandardGravity,
    /// Seconds.
    Seconds,
    /// The firmware's own unit, unconverted (motor commands, PID terms,
    /// RC commands); see the field's range where known.
    Raw,
    /// A unit named by the log itself.
    Named(String),
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Unit::RadPerSecond => f.write_str("rad/s"),
            Unit::StandardGravity => f.write_str("g"),
            Unit::Seconds => f.write_str("s"),
            Unit::Raw => f.write_str("raw"),
            Unit::Named(s) => f.write_str(s),
        }
    }
}

/// One signal of a topic.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// The name the log gives it (`gyroADC[0]`, `gyro.x`, `xyz[0]`).
    pub name: String,
    /// Unit of `values`.
    pub unit: Unit,
    /// The command range `[low, high]` where the log states it (motor
    /// commands): the airborne detection scales motor levels by it.
    pub range: Option<[f64; 2]>,
    /// One value per sample of the topic.
    pub values: Vec<f64>,
}

/// Fields sampled together on one clock: Betaflight's main frames,
/// a Crazyflie event type, a ULog topic instance.
#[derive(Clone, Debug, PartialEq)]
pub struct Topic {
    /// The topic's name (`main`, `slow`, `fixedFrequency`,
    /// `vehicle_angular_velocity`, `actuator_outputs#1` for a second
    /// instance).
    pub name: String,
    /// Sample times in seconds from the log's own clock origin, one per
    /// sample, non-decreasing.
    pub t: Vec<f64>,
    /// The fields, each with `t.len()` values.
    pub fields: Vec<Field>,
}

impl Topic {
    /// Puts the samples in time order (stable) when they are not: a ULog
    /// topic's or a GPS stream's timestamps come from the sender.
    pub(crate) fn sort_by_time(&mut self) {
        if self.t.windows(2).all(|w| w[0] <= w[1]) {
            return;
        }
        let mut order: Vec<usize> = (0..self.t.len()).collect();
        order.sort_by(|&a, &b| self.t[a].total_cmp(&self.t[b]));
        self.t = order.iter().map(|&k| self.t[k]).collect();
        for f in &mut self.fields {
            f.values = order
                .iter()
                .map(|&k| f.values.get(k).copied().unwrap_or(f64::NAN))
                .collect();
        }
    }

    /// The field named `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }
}

/// Something read past or repaired while salvaging a damaged log
/// ([`ReadOptions::salvage`](crate::ReadOptions)).
#[derive(Clone, Debug, PartialEq)]
pub struct Issue {
    /// Byte offset from the start of the file.
    pub offset: u64,
    /// What was wrong and what was done.
    pub text: String,
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "byte offset {}: {}", self.offset, self.text)
    }
}

/// One log as read: a file may hold several (Betaflight writes a new one
/// at every arming).
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// Its format.
    pub format: LogFormat,
    /// Byte offset of its first byte in the file.
    pub offset: u64,
    /// Its topics.
    pub topics: Vec<Topic>,
    /// Header facts worth keeping (firmware, craft name, log rate), as
    /// `(key, value)`.
    pub info: Vec<(String, String)>,
    /// Damage found and read past (only with salvage; empty otherwise).
    pub issues: Vec<Issue>,
}

impl Log {
    /// The topic named `name`.
    pub fn topic(&self, name: &str) -> Option<&Topic> {
        self.topics.iter().find(|t| t.name == name)
    }
}
