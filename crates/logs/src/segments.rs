//! Airborne segments from the motor commands.

use crate::error::{LogError, Result};
use crate::select::Resolved;

/// How airborne segments are found: the mean motor command, scaled by
/// each command's range to 0 (its low end) ..= 1 (its high end), its
/// 0.1 s moving average above `threshold`; stretches below it shorter than
/// `bridge_s` are bridged (flips and dives at idle throttle), segments
/// shorter than `min_duration_s` dropped, `trim_s` cut from both ends
/// (spool-up and touch-down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirborneSettings {
    /// Motor level (fraction of the command range) above which the
    /// aircraft counts as flying. Default 0.05: hover is about 0.2 on
    /// the 5-inch Betaflight quad and 0.6 on the Crazyflie, both sit at
    /// 0 on the ground.
    pub threshold: f64,
    /// Shortest segment kept, seconds (default 1).
    pub min_duration_s: f64,
    /// Longest stretch below the threshold inside one flight, seconds
    /// (default 3).
    pub bridge_s: f64,
    /// Cut from both ends of each segment, seconds (default 0.5).
    pub trim_s: f64,
}

impl Default for AirborneSettings {
    fn default() -> Self {
        AirborneSettings {
            threshold: 0.05,
            min_duration_s: 1.0,
            bridge_s: 3.0,
            trim_s: 0.5,
        }
    }
}

/// A time interval `[start, end]`, seconds in the log's clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Start.
    pub start: f64,
    /// End.
    pub end: f64,
}

/// Smoothing window of the motor level, seconds.
const WINDOW_S: f64 = 0.1;

/// The airborne segments within `span`, from the `motors` (commands with
/// a stated range; without one, the observed minimum and maximum). Works
/// on the first motor's sample times (the others held at their latest
/// sample), so its memory follows the log's size, not its time span.
pub(crate) fn airborne(
    motors: &[(String, Resolved)],
    span: Span,
    s: &AirborneSettings,
) -> Result<Vec<Span>> {
    let Some((_, base)) = motors.first() else {
        return Err(LogError::Invalid(
            "airborne segments are found from the motor commands: select at least one input".into(),
        ));
    };
    if !s.threshold.is_finite() {
        return Err(LogError::Invalid(format!(
            "airborne detection: the threshold (a fraction of the motor command range) must be a finite number, found {}",
            s.threshold
        )));
    }
    for (name, v) in [
        ("minimum duration", s.min_duration_s),
        ("bridged gap", s.bridge_s),
        ("trim", s.trim_s),
    ] {
        if v.is_nan() || v < 0.0 {
            return Err(LogError::Invalid(format!(
                "airborne detection: the {name} must be a number of seconds >= 0, found {v}"
            )));
        }
    }
    let a = base.topic.t.partition_point(|&x| x < span.start);
    let b = base.topic.t.partition_point(|&x| x <= span.end);
    let t = &base.topic.t[a..b];
    let mut level = vec![0.0; t.len()];
    for (_, r) in motors {
        let vals = &r.field.values;
        let finite = || vals.iter().copied().filter(|v| v.is_finite());
        let [lo, hi] = r.field.range.unwrap_or_else(|| {
            [
                finite().fold(f64::INFINITY, f64::min),
                finite().fold(f64::NEG_INFINITY, f64::max),
            ]
        });
        let scale = if hi > lo { 1.0 / (hi - lo) } else { 0.0 };
        let mut j = 0;
        for (l, &ti) in level.iter_mut().zip(t) {
            // The latest sample at or before ti (the same index on the same topic).
            while j + 1 < r.topic.t.len() && r.topic.t[j + 1] <= ti {
                j += 1;
            }
            let v = vals.get(j).copied().unwrap_or(f64::NAN);
            // Missing (NaN: disarmed PX4 motors) counts as stopped.
            *l += if v.is_finite() { (v - lo) * scale } else { 0.0 } / motors.len() as f64;
        }
    }
    // Centred moving average over WINDOW_S.
    let mut prefix = vec![0.0; level.len() + 1];
    for (k, l) in level.iter().enumerate() {
        prefix[k + 1] = prefix[k] + l;
    }
    let (mut lo, mut hi) = (0, 0);
    let mut runs: Vec<Span> = Vec::new();
    let mut open: Option<f64> = None;
    let mut last = f64::NAN;
    for &tk in t {
        while t[lo] < tk - WINDOW_S / 2.0 {
            lo += 1;
        }
        while hi < t.len() && t[hi] <= tk + WINDOW_S / 2.0 {
            hi += 1;
        }
        let mean = (prefix[hi] - prefix[lo]) / (hi - lo).max(1) as f64;
        match (mean > s.threshold, open) {
            (true, None) => open = Some(tk),
            (false, Some(a)) => {
                runs.push(Span { start: a, end: tk });
                open = None;
            }
            _ => {}
        }
        last = tk;
    }
    if let Some(a) = open {
        runs.push(Span {
            start: a,
            end: last,
        });
    }
    let mut merged: Vec<Span> = Vec::new();
    for r in runs {
        match merged.last_mut() {
            Some(prev) if r.start - prev.end < s.bridge_s => prev.end = r.end,
            _ => merged.push(r),
        }
    }
    Ok(merged
        .into_iter()
        .map(|r| Span {
            start: (r.start + s.trim_s).max(span.start),
            end: (r.end - s.trim_s).min(span.end),
        })
        .filter(|r| r.end - r.start >= s.min_duration_s.max(WINDOW_S))
        .collect())
}
