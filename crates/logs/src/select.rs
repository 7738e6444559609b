//! Which signals to take from a log: `name=source` specifications, their
//! lookup among the topics' fields, and each format's default selection.

use crate::error::{LogError, Result};
use crate::model::{Field, Log, LogFormat, Topic};

/// A signal to take: the name it gets in the output and the field it
/// comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SignalSpec {
    /// Output column name (`p`, `motor0`).
    pub name: String,
    /// The field: `topic.field` (`vehicle_angular_velocity.xyz[0]`,
    /// `main.gyroADC[0]`) or a field name found in exactly one topic
    /// (`gyroADC[0]`, `gyro.x`). A name whose `[0]`, `[1]`, ... elements
    /// exist stands for all of them (`vehicle_angular_velocity.xyz`),
    /// named `name0`, `name1`, ...
    pub source: String,
}

impl SignalSpec {
    /// Parses a comma-separated list of `name=source` or `source` (then
    /// the name is the source). A name of the format's default selection
    /// alone (`p`, `motor0`) is resolved by [`resolve`] through
    /// [`default_signals`].
    ///
    /// ```
    /// use kestrel_logs::SignalSpec;
    /// let s = SignalSpec::parse_list("p=gyroADC[0], motor[1]").unwrap();
    /// assert_eq!(s[0].name, "p");
    /// assert_eq!(s[1].source, "motor[1]");
    /// ```
    pub fn parse_list(text: &str) -> Result<Vec<SignalSpec>> {
        let mut out = Vec::new();
        for part in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, source) = match part.split_once('=') {
                Some((n, s)) => (n.trim(), s.trim()),
                None => (part, part),
            };
            if name.is_empty() || source.is_empty() || name.contains(['"', '\n']) {
                return Err(LogError::Signal {
                    name: part.to_string(),
                    reason: "expected name=source or a field name".into(),
                });
            }
            out.push(SignalSpec {
                name: name.to_string(),
                source: source.to_string(),
            });
        }
        Ok(out)
    }

    fn new(name: impl Into<String>, source: impl Into<String>) -> Self {
        SignalSpec {
            name: name.into(),
            source: source.into(),
        }
    }
}

/// The signals kestrel identifies from, per format.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DefaultSignals {
    /// Motor commands: `motor0..motor3` (Betaflight `motor[k]`, PX4
    /// `actuator_motors.control[k]` that hold numbers) or `m1..m4`
    /// (Crazyflie `motor.m1..m4`).
    pub inputs: Vec<SignalSpec>,
    /// Body rates `p, q, r` in rad/s (Betaflight `gyroADC[0..2]`,
    /// Crazyflie `gyro.x/y/z`, PX4 `vehicle_angular_velocity.xyz[0..2]`).
    pub outputs: Vec<SignalSpec>,
}

/// The default selection for `log`'s format (see [`DefaultSignals`]).
pub fn default_signals(log: &Log) -> DefaultSignals {
    let rates = |src: [&str; 3]| {
        ["p", "q", "r"]
            .iter()
            .zip(src)
            .map(|(n, s)| SignalSpec::new(*n, s))
            .collect()
    };
    match log.format {
        LogFormat::Betaflight => DefaultSignals {
            inputs: (0..4)
                .map(|k| SignalSpec::new(format!("motor{k}"), format!("motor[{k}]")))
                .collect(),
            outputs: rates(["gyroADC[0]", "gyroADC[1]", "gyroADC[2]"]),
        },
        LogFormat::Crazyflie => DefaultSignals {
            inputs: (1..=4)
                .map(|k| SignalSpec::new(format!("m{k}"), format!("motor.m{k}")))
                .collect(),
            outputs: rates(["gyro.x", "gyro.y", "gyro.z"]),
        },
        LogFormat::Ulog => {
            let used = |f: &Field| f.values.iter().any(|v| v.is_finite() && *v != 0.0);
            let motors: Vec<SignalSpec> = match log.topic("actuator_motors") {
                Some(t) => (0..12)
                    .filter(|k| t.field(&format!("control[{k}]")).is_some_and(used))
                    .map(|k| {
                        SignalSpec::new(
                            format!("motor{k}"),
                            format!("actuator_motors.control[{k}]"),
                        )
                    })
                    .collect(),
                None => (0..4)
                    .map(|k| {
                        SignalSpec::new(
                            format!("motor{k}"),
                            format!("actuator_outputs.output[{k}]"),
                        )
                    })
                    .collect(),
            };
            DefaultSignals {
                inputs: motors,
                outputs: rates([
                    "vehicle_angular_velocity.xyz[0]",
                    "vehicle_angular_velocity.xyz[1]",
                    "vehicle_angular_velocity.xyz[2]",
                ]),
            }
        }
    }
}

/// A signal found in a log.
#[derive(Clone, Copy, Debug)]
pub struct Resolved<'a> {
    /// The topic it belongs to (its clock).
    pub topic: &'a Topic,
    /// The field.
    pub field: &'a Field,
}

/// Finds `source` as `topic.field` or as a field of exactly one topic.
fn find<'a>(log: &'a Log, source: &str) -> std::result::Result<Option<Resolved<'a>>, String> {
    for topic in &log.topics {
        if let Some(rest) = source
            .strip_prefix(topic.name.as_str())
            .and_then(|r| r.strip_prefix('.'))
            && let Some(field) = topic.field(rest)
        {
            return Ok(Some(Resolved { topic, field }));
        }
    }
    let hits: Vec<Resolved> = log
        .topics
        .iter()
        .filter_map(|topic| topic.field(source).map(|field| Resolved { topic, field }))
        .collect();
    match hits.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(*one)),
        many => Err(format!(
            "in several topics; name one: {}",
            many.iter()
                .map(|r| format!("{}.{}", r.topic.name, r.field.name))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Resolves `specs` in `log`: each to one field, or a vector name to its
/// elements. A spec whose source is a name of the format's default
/// selection (`p`, `motor0`) and no field of the log takes that default.
pub fn resolve<'a>(log: &'a Log, specs: &[SignalSpec]) -> Result<Vec<(String, Resolved<'a>)>> {
    let defaults = default_signals(log);
    let mut out = Vec::new();
    for spec in specs {
        let err = |reason: String| LogError::Signal {
            name: spec.name.clone(),
            reason,
        };
        if let Some(r) = find(log, &spec.source).map_err(err)? {
            out.push((spec.name.clone(), r));
            continue;
        }
        let mut k = 0;
        let mut elements = Vec::new();
        while let Some(r) = find(log, &format!("{}[{k}]", spec.source)).map_err(err)? {
            elements.push((format!("{}{k}", spec.name), r));
            k += 1;
        }
        if !elements.is_empty() {
            out.extend(elements);
            continue;
        }
        let default = defaults
            .inputs
            .iter()
            .chain(&defaults.outputs)
            .find(|d| d.name == spec.source && spec.name == spec.source);
        if let Some(d) = default
            && let Some(r) = find(log, &d.source).map_err(err)?
        {
            out.push((spec.name.clone(), r));
            continue;
        }
        return Err(err(format!(
            "no such field in this {} log; it has {}",
            log.format,
            field_list(log)
        )));
    }
    let mut names: Vec<&str> = out.iter().map(|(n, _)| n.as_str()).collect();
    names.sort_unstable();
    if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
        return Err(LogError::Signal {
            name: w[0].to_string(),
            reason: "selected twice; give each signal its own name (name=source)".into(),
        });
    }
    Ok(out)
}

/// The log's fields as `topic.field`, at most 60.
fn field_list(log: &Log) -> String {
    let all: Vec<String> = log
        .topics
        .iter()
        .flat_map(|t| {
            t.fields
                .iter()
                .map(move |f| format!("{}.{}", t.name, f.name))
        })
        .collect();
    let shown = all.iter().take(60).cloned().collect::<Vec<_>>().join(", ");
    if all.len() > 60 {
        format!("{shown} and {} more", all.len() - 60)
    } else {
        shown
    }
}
