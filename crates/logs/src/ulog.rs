//! PX4 ULog (`.ulg`) through the `px4-ulog` crate (PX4's own Rust parser).
//!
//! The record framing (a 16-byte header, then records of a `u16` size, a
//! type byte and the payload) is walked here, so that every error names the
//! offset of its record and a truncated record is found before the parser
//! sees it; each complete record goes to `px4_ulog`'s `LogParser`, whose
//! data callback hands over every logged sample with its flattened format.
//! Records the parser would index past their end are refused here first.

use crate::error::{LogError, Result};
use crate::model::{Field, Issue, Log, LogFormat, ReadOptions, Topic, ULOG_MAGIC, Unit};
use crate::number::Number;
use px4_ulog::full_parser::FlattenedFieldType;
use px4_ulog::stream_parser::{DataMessage, LogParser};
use std::cell::Cell;
use std::collections::BTreeMap;

const FORMAT: LogFormat = LogFormat::Ulog;

fn corrupt(offset: usize, expected: &str, found: impl Into<String>) -> LogError {
    LogError::Corrupt {
        format: FORMAT,
        offset: offset as u64,
        expected: expected.to_string(),
        found: found.into(),
    }
}

/// The samples of one topic instance, gathered by the data callback.
#[derive(Default)]
struct Gathered {
    name: String,
    multi_id: u8,
    /// Field name, type, byte offset.
    fields: Vec<(String, FlattenedFieldType, usize)>,
    ts_offset: Option<usize>,
    t: Vec<f64>,
    values: Vec<Vec<f64>>,
}

/// The number type of a ULog field (`char` fields are not numbers).
fn number(t: &FlattenedFieldType) -> Option<Number> {
    Some(match t {
        FlattenedFieldType::Int8 => Number::I8,
        FlattenedFieldType::UInt8 => Number::U8,
        FlattenedFieldType::Bool => Number::Bool,
        FlattenedFieldType::Int16 => Number::I16,
        FlattenedFieldType::UInt16 => Number::U16,
        FlattenedFieldType::Int32 => Number::I32,
        FlattenedFieldType::UInt32 => Number::U32,
        FlattenedFieldType::Float => Number::F32,
        FlattenedFieldType::Int64 => Number::I64,
        FlattenedFieldType::UInt64 => Number::U64,
        FlattenedFieldType::Double => Number::F64,
        FlattenedFieldType::Char => return None,
    })
}

fn gather(map: &mut BTreeMap<u16, Gathered>, msg: &DataMessage) {
    let g = map.entry(msg.msg_id).or_insert_with(|| {
        let f = msg.flattened_format;
        let fields: Vec<_> = f
            .fields
            .iter()
            .filter(|x| {
                x.flattened_field_name != "timestamp"
                    && !x.flattened_field_name.starts_with("_padding")
                    && number(&x.field_type).is_some()
            })
            .map(|x| {
                (
                    x.flattened_field_name.clone(),
                    x.field_type.clone(),
                    usize::from(x.offset),
                )
            })
            .collect();
        let n = fields.len();
        Gathered {
            name: f.message_name.clone(),
            multi_id: msg.multi_id.value(),
            fields,
            ts_offset: f.timestamp_field.as_ref().map(|t| usize::from(t.offset)),
            t: Vec::new(),
            values: vec![Vec::new(); n],
        }
    });
    let read = |off: usize, t: &FlattenedFieldType| {
        let t = number(t)?;
        msg.data.get(off..off + t.size()).map(|b| t.decode(b))
    };
    let Some(t) = g
        .ts_offset
        .and_then(|o| read(o, &FlattenedFieldType::UInt64))
    else {
        return;
    };
    g.t.push(t * 1e-6);
    for ((_, ty, off), out) in g.fields.iter().zip(g.values.iter_mut()) {
        out.push(read(*off, ty).unwrap_or(f64::NAN));
    }
}

/// The shortest payload of a record type that the parser reads without
/// checking, and the position of a key length byte it trusts.
fn payload_check(kind: u8, p: &[u8]) -> std::result::Result<(), String> {
    let (min, key_len_at) = match kind {
        b'B' => (40, None),
        b'I' | b'P' => (1, Some(0)),
        b'M' | b'Q' => (2, Some(1)),
        b'A' => (3, None),
        b'R' | b'D' | b'O' => (2, None),
        b'L' => (9, None),
        b'C' => (11, None),
        b'S' => (8, None),
        _ => (0, None),
    };
    if p.len() < min {
        return Err(format!(
            "a {} record of {} bytes (at least {min} needed)",
            Kind(kind),
            p.len()
        ));
    }
    if let Some(k) = key_len_at {
        let key_end = k + 1 + usize::from(p[k]);
        if key_end > p.len() {
            return Err(format!(
                "a {} record whose key length runs to byte {key_end} of its {}-byte payload",
                Kind(kind),
                p.len()
            ));
        }
    }
    Ok(())
}

/// Reads a ULog file.
pub(crate) fn read(bytes: &[u8], opts: &ReadOptions) -> Result<Log> {
    if bytes.len() < 16 {
        return Err(LogError::Truncated {
            format: FORMAT,
            offset: 0,
            expected: "the 16-byte ULog header".into(),
            len: bytes.len() as u64,
        });
    }
    if !bytes.starts_with(ULOG_MAGIC) {
        return Err(corrupt(
            0,
            "the ULog magic bytes \"ULog\" 01 12 35",
            "other bytes",
        ));
    }
    let mut map: BTreeMap<u16, Gathered> = BTreeMap::new();
    let mut issues = Vec::new();
    let at = Cell::new(0usize);
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        walk(bytes, opts, &mut map, &mut issues, &at)
    }));
    match outcome {
        Ok(r) => r?,
        Err(_) => {
            return Err(corrupt(
                at.get(),
                "a record the px4-ulog parser accepts",
                "one that made it fail",
            ));
        }
    }
    let topics = map
        .into_values()
        .filter(|g| !g.t.is_empty())
        .map(|g| {
            let name = if g.multi_id == 0 {
                g.name.clone()
            } else {
                format!("{}#{}", g.name, g.multi_id)
            };
            let fields = g
                .fields
                .into_iter()
                .zip(g.values)
                .map(|((field, _, _), values)| {
                    let (unit, range) = unit_of(&g.name, &field);
                    Field {
                        name: field,
                        unit,
                        range,
                        values,
                    }
                })
                .collect();
            let mut topic = Topic {
                name,
                t: g.t,
                fields,
            };
            topic.sort_by_time();
            topic
        })
        .collect();
    Ok(Log {
        format: FORMAT,
        offset: 0,
        topics,
        info: vec![("version".into(), bytes[7].to_string())],
        issues,
    })
}

/// Walks the records and feeds them to the parser.
fn walk(
    bytes: &[u8],
    opts: &ReadOptions,
    map: &mut BTreeMap<u16, Gathered>,
    issues: &mut Vec<Issue>,
    at: &Cell<usize>,
) -> Result<()> {
    let mut cb = |m: &DataMessage| gather(map, m);
    let mut parser = LogParser::default();
    parser.set_data_message_callback(&mut cb);
    parser
        .consume_bytes(&bytes[..16])
        .map_err(|e| corrupt(0, "a ULog header", e.to_string()))?;
    let mut pos = 16;
    let mut appended: Vec<usize> = Vec::new();
    while pos < bytes.len() {
        at.set(pos);
        if let Some(&next) = appended.first()
            && pos > next
        {
            pos = next;
            appended.remove(0);
            continue;
        }
        let rest = &bytes[pos..];
        let result = if rest.len() < 3 {
            Err(LogError::Truncated {
                format: FORMAT,
                offset: pos as u64,
                expected: "a record header (size u16, type byte)".into(),
                len: bytes.len() as u64,
            })
        } else {
            let size = usize::from(u16::from_le_bytes([rest[0], rest[1]]));
            let kind = rest[2];
            if rest.len() < 3 + size {
                Err(LogError::Truncated {
                    format: FORMAT,
                    offset: pos as u64,
                    expected: format!("a {} record of {} bytes", Kind(kind), 3 + size),
                    len: bytes.len() as u64,
                })
            } else {
                let payload = &rest[3..3 + size];
                payload_check(kind, payload)
                    .map_err(|found| corrupt(pos, "a record as long as its type needs", found))
                    .and_then(|()| {
                        if kind == b'B' {
                            appended = flag_offsets(payload);
                        }
                        parser.consume_bytes(&rest[..3 + size]).map_err(|e| {
                            corrupt(
                                pos,
                                &format!("a valid {} record", Kind(kind)),
                                brief(&e.to_string()),
                            )
                        })
                    })
                    .map(|()| 3 + size)
            }
        };
        match result {
            Ok(n) => pos += n,
            Err(e) if opts.salvage => {
                issues.push(Issue {
                    offset: pos as u64,
                    text: format!("{e}; the log is kept up to here"),
                });
                break;
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// The appended-data offsets of a flag bits record, in order.
fn flag_offsets(p: &[u8]) -> Vec<usize> {
    let mut v: Vec<usize> = (0..3)
        .filter_map(|k| {
            let b = p.get(16 + 8 * k..24 + 8 * k)?;
            let mut a = [0u8; 8];
            a.copy_from_slice(b);
            usize::try_from(u64::from_le_bytes(a)).ok()
        })
        .filter(|&o| o != 0)
        .collect();
    v.sort_unstable();
    v
}

/// Units of the topics kestrel reads by default (PX4 uses SI units and
/// body FRD axes; commands are normalised).
fn unit_of(topic: &str, field: &str) -> (Unit, Option<[f64; 2]>) {
    match (topic, field) {
        ("vehicle_angular_velocity", f) if f.starts_with("xyz[") => (Unit::RadPerSecond, None),
        ("sensor_combined", f) if f.starts_with("gyro_rad[") => (Unit::RadPerSecond, None),
        ("actuator_motors", f) if f.starts_with("control[") => (Unit::Raw, Some([0.0, 1.0])),
        ("vehicle_torque_setpoint" | "vehicle_thrust_setpoint", f) if f.starts_with("xyz[") => {
            (Unit::Raw, Some([-1.0, 1.0]))
        }
        _ => (Unit::Raw, None),
    }
}

/// The parser's message without the format dump it appends.
fn brief(text: &str) -> String {
    let head = text.split(", format:").next().unwrap_or(text);
    let head = head.lines().next().unwrap_or(head);
    match head.char_indices().nth(160) {
        Some((i, _)) => format!("{}...", &head[..i]),
        None => head.to_string(),
    }
}

/// A record type byte as the ULog specification names it (`'D'`), or in
/// hexadecimal when it is no letter.
struct Kind(u8);

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_ascii_graphic() {
            write!(f, "'{}'", self.0 as char)
        } else {
            write!(f, "0x{:02X}", self.0)
        }
    }
}
