//! Crazyflie uSD-card binary logs (the `usddeck` format, versions 1 and 2).
//!
//! Byte 0 is `0xBC`, then a little-endian `u16` version and a `u16` count
//! of event types; each event type is a `u16` id, a NUL-terminated name, a
//! `u16` count of variables and that many NUL-terminated `name(T)` strings,
//! `T` a Python `struct` code. Records follow: `u16` event id, a timestamp
//! (`u32` ms in version 1, `u64` µs in version 2), the packed little-endian
//! values. The firmware ends the file with a CRC-32 (IEEE, as zlib's
//! `crc32`) of everything before it, little-endian; it is checked when
//! present.

use crate::error::{LogError, Result};
use crate::model::{CRAZYFLIE_MAGIC, Field, Issue, Log, LogFormat, ReadOptions, Topic, Unit};
use crate::number::Number;

const FORMAT: LogFormat = LogFormat::Crazyflie;
/// Largest forward jump between two records' timestamps taken as real.
const MAX_JUMP_S: f64 = 10.0;

/// A variable type from its Python `struct` code.
fn var_type(c: u8) -> Option<Number> {
    Some(match c {
        b'b' => Number::I8,
        b'B' => Number::U8,
        b'?' => Number::Bool,
        b'h' => Number::I16,
        b'H' => Number::U16,
        b'i' | b'l' => Number::I32,
        b'I' | b'L' => Number::U32,
        b'q' => Number::I64,
        b'Q' => Number::U64,
        b'e' => Number::F16,
        b'f' => Number::F32,
        b'd' => Number::F64,
        _ => return None,
    })
}

/// One event type of the header.
struct EventType {
    id: u16,
    name: String,
    vars: Vec<(String, Number)>,
    size: usize,
    t: Vec<f64>,
    values: Vec<Vec<f64>>,
}

/// A cursor over the file that names offsets in its errors.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        match end {
            Some(end) => {
                let s = &self.bytes[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(LogError::Truncated {
                format: FORMAT,
                offset: self.pos as u64,
                expected: format!("{what} ({n} bytes)"),
                len: self.bytes.len() as u64,
            }),
        }
    }

    fn u16(&mut self, what: &str) -> Result<u16> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    /// A NUL-terminated UTF-8 string.
    fn cstr(&mut self, what: &str) -> Result<String> {
        let start = self.pos;
        let rest = &self.bytes[start..];
        let Some(n) = rest.iter().position(|&b| b == 0) else {
            return Err(LogError::Truncated {
                format: FORMAT,
                offset: start as u64,
                expected: format!("{what} ended by a NUL byte"),
                len: self.bytes.len() as u64,
            });
        };
        let s = std::str::from_utf8(&rest[..n])
            .map_err(|_| corrupt(start, what, "bytes that are not UTF-8"))?;
        self.pos = start + n + 1;
        Ok(s.to_string())
    }
}

fn corrupt(offset: usize, expected: &str, found: impl Into<String>) -> LogError {
    LogError::Corrupt {
        format: FORMAT,
        offset: offset as u64,
        expected: expected.to_string(),
        found: found.into(),
    }
}

/// Splits `name(T)` into the name and its type.
fn parse_var(text: &str, offset: usize) -> Result<(String, Number)> {
    let expected = "a variable \"name(T)\" with T a struct code (b B h H i I q Q e f d ?)";
    let (name, code) = text
        .strip_suffix(')')
        .and_then(|s| s.rsplit_once('('))
        .ok_or_else(|| corrupt(offset, expected, format!("\"{text}\"")))?;
    let ty = match code.as_bytes() {
        [c] => var_type(*c),
        _ => None,
    }
    .ok_or_else(|| corrupt(offset, expected, format!("\"{text}\"")))?;
    if name.is_empty() {
        return Err(corrupt(offset, expected, format!("\"{text}\"")));
    }
    Ok((name.to_string(), ty))
}

/// Reads a Crazyflie uSD log.
pub(crate) fn read(bytes: &[u8], opts: &ReadOptions) -> Result<Log> {
    let mut c = Cursor { bytes, pos: 0 };
    let magic = c.take(1, "the magic byte 0xBC")?;
    if magic[0] != CRAZYFLIE_MAGIC {
        return Err(corrupt(
            0,
            "the magic byte 0xBC",
            format!("0x{:02X}", magic[0]),
        ));
    }
    let version_at = c.pos;
    let version = c.u16("the format version")?;
    if !(version == 1 || version == 2) {
        return Err(corrupt(
            version_at,
            "format version 1 or 2",
            version.to_string(),
        ));
    }
    let n_events = c.u16("the count of event types")?;
    let mut events: Vec<EventType> = Vec::new();
    for _ in 0..n_events {
        let at = c.pos;
        let id = c.u16("an event type id")?;
        if events.iter().any(|e| e.id == id) {
            return Err(corrupt(
                at,
                "a new event type id",
                format!("id {id} a second time"),
            ));
        }
        let name = c.cstr("an event name")?;
        let n_vars = c.u16("a count of variables")?;
        let mut vars = Vec::new();
        for _ in 0..n_vars {
            let at = c.pos;
            let text = c.cstr("a variable \"name(T)\"")?;
            vars.push(parse_var(&text, at)?);
        }
        let size = vars.iter().map(|(_, t)| t.size()).sum();
        let n = vars.len();
        events.push(EventType {
            id,
            name,
            vars,
            size,
            t: Vec::new(),
            values: vec![Vec::new(); n],
        });
    }
    let ts_size = if version == 1 { 4 } else { 8 };
    let mut issues = Vec::new();
    let mut last_t: Option<f64> = None;
    let records_start = c.pos;
    loop {
        let at = c.pos;
        let rest = &bytes[at..];
        if rest.is_empty() {
            break;
        }
        if rest.len() == 4 && at > records_start {
            check_crc(bytes, at, opts, &mut issues)?;
            break;
        }
        if rest.iter().all(|&b| b == 0xff) {
            // Erased flash after the last record.
            break;
        }
        match record(&mut c, &mut events, ts_size, version, &mut last_t) {
            Ok(()) => {}
            Err(e) if opts.salvage => {
                issues.push(Issue {
                    offset: at as u64,
                    text: format!("{e}; the log is kept up to here"),
                });
                break;
            }
            Err(e) => return Err(e),
        }
    }
    let topics = events
        .into_iter()
        .filter(|e| !e.t.is_empty())
        .map(|e| Topic {
            name: e.name,
            t: e.t,
            fields: e
                .vars
                .into_iter()
                .zip(e.values)
                .map(|((name, _), values)| field(name, values))
                .collect(),
        })
        .collect();
    Ok(Log {
        format: FORMAT,
        offset: 0,
        topics,
        info: vec![("version".into(), version.to_string())],
        issues,
    })
}

/// One record at the cursor.
fn record(
    c: &mut Cursor,
    events: &mut [EventType],
    ts_size: usize,
    version: u16,
    last_t: &mut Option<f64>,
) -> Result<()> {
    let at = c.pos;
    let id = c.u16("a record's event id")?;
    let ids = || {
        events
            .iter()
            .map(|e| e.id.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let Some(k) = events.iter().position(|e| e.id == id) else {
        return Err(corrupt(
            at,
            &format!(
                "a record starting with an event id of the header ({})",
                ids()
            ),
            format!("id {id}"),
        ));
    };
    let ev = &mut events[k];
    let what = format!(
        "a \"{}\" record ({} bytes of timestamp and values)",
        ev.name,
        ts_size + ev.size
    );
    c.pos = at;
    let rec = c.take(2 + ts_size + ev.size, &what)?;
    let tb = &rec[2..2 + ts_size];
    let t = if version == 1 {
        f64::from(u32::from_le_bytes([tb[0], tb[1], tb[2], tb[3]])) * 1e-3
    } else {
        let mut a = [0u8; 8];
        a.copy_from_slice(tb);
        u64::from_le_bytes(a) as f64 * 1e-6
    };
    if let Some(prev) = *last_t
        && !(t >= prev && t - prev <= MAX_JUMP_S)
    {
        return Err(corrupt(
            at + 2,
            &format!(
                "a timestamp from {prev:.6} s to {:.6} s (no step back, at most {MAX_JUMP_S} s forward)",
                prev + MAX_JUMP_S
            ),
            format!("{t:.6} s"),
        ));
    }
    *last_t = Some(t);
    ev.t.push(t);
    let mut pos = 2 + ts_size;
    for ((_, ty), out) in ev.vars.iter().zip(ev.values.iter_mut()) {
        let n = ty.size();
        out.push(ty.decode(&rec[pos..pos + n]));
        pos += n;
    }
    Ok(())
}

/// Checks the CRC-32 trailer at `at`.
fn check_crc(bytes: &[u8], at: usize, opts: &ReadOptions, issues: &mut Vec<Issue>) -> Result<()> {
    let stored = u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let computed = crc32(&bytes[..at]);
    if stored == computed {
        return Ok(());
    }
    let e = corrupt(
        at,
        &format!(
            "a record or the CRC-32 trailer of bytes 0..{at}, 0x{computed:08X} (a byte before offset {at} is damaged)"
        ),
        format!("4 bytes 0x{stored:08X}"),
    );
    if opts.salvage {
        issues.push(Issue {
            offset: at as u64,
            text: format!("{e}; the records are kept"),
        });
        Ok(())
    } else {
        Err(e)
    }
}

/// CRC-32 (IEEE 802.3, reflected, as zlib).
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    let mut table = [0u32; 256];
    for (i, e) in table.iter_mut().enumerate() {
        let mut c = i as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
        *e = c;
    }
    let mut crc = !0u32;
    for &b in bytes {
        crc = table[((crc ^ u32::from(b)) & 0xff) as usize] ^ (crc >> 8);
    }
    !crc
}

/// A field with the unit its name implies: gyro (deg/s) converted to
/// rad/s, accelerometer in g, motor commands raw 16-bit PWM.
fn field(name: String, mut values: Vec<f64>) -> Field {
    let (unit, range) = if name.starts_with("gyro.") {
        for v in &mut values {
            *v = v.to_radians();
        }
        (Unit::RadPerSecond, None)
    } else if name.starts_with("acc.") {
        (Unit::StandardGravity, None)
    } else if name.starts_with("motor.m") {
        (Unit::Raw, Some([0.0, 65535.0]))
    } else {
        (Unit::Raw, None)
    };
    Field {
        name,
        unit,
        range,
        values,
    }
}
