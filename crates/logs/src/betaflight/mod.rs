//! Betaflight (Cleanflight, INAV) blackbox logs, read by this crate's own
//! decoder: a text header of `H name:value` lines with the field
//! definitions, then intra (`I`) and inter (`P`) main frames, slow (`S`),
//! GPS (`G`, `H`) and event (`E`) frames of variable-byte encoded,
//! predicted values. A file may hold several logs back to back; each
//! starts with `H Product:Blackbox`.

mod decode;
mod defs;
mod header;

use crate::error::{LogError, Result};
use crate::model::{BETAFLIGHT_MAGIC, Field, Issue, Log, ReadOptions, Topic, Unit};
use decode::{Reader, Stop};
use defs::{FORMAT, Predictor, corrupt};
use header::{FrameDef, Header};

/// Largest forward step of the main frames' clock taken as real (as
/// Betaflight's own decoder).
const MAX_TIME_JUMP_US: i64 = 10_000_000;
/// Largest forward step of the loop iteration counter taken as real.
const MAX_ITERATION_JUMP: i64 = 5_000 * 10;

/// Reads every log of a blackbox file.
pub(crate) fn read_all(bytes: &[u8], opts: &ReadOptions) -> Result<Vec<Log>> {
    if bytes.len() < BETAFLIGHT_MAGIC.len() {
        return Err(LogError::Truncated {
            format: FORMAT,
            offset: 0,
            expected: "the header line \"H Product:Blackbox ...\"".into(),
            len: bytes.len() as u64,
        });
    }
    let starts: Vec<usize> = find_all(bytes, BETAFLIGHT_MAGIC);
    if starts.first() != Some(&0) {
        return Err(corrupt(
            0,
            "\"H Product:Blackbox\" at the start of the file",
            "other bytes",
        ));
    }
    let mut logs = Vec::new();
    for (k, &start) in starts.iter().enumerate() {
        let end = starts.get(k + 1).copied().unwrap_or(bytes.len());
        logs.push(read_one(bytes, start, end, opts)?);
    }
    Ok(logs)
}

fn find_all(hay: &[u8], needle: &[u8]) -> Vec<usize> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + needle.len() <= hay.len() {
        if hay[i..].starts_with(needle) {
            out.push(i);
            i += needle.len();
        } else {
            i += 1;
        }
    }
    out
}

/// The decoder's state for one log.
struct State<'h> {
    h: &'h Header,
    /// Index of `time`, `loopIteration`, `motor[0]` among the I fields.
    time_ix: usize,
    iter_ix: usize,
    motor0_ix: Option<usize>,
    prev: Option<Vec<i64>>,
    prev2: Option<Vec<i64>>,
    home: Vec<i64>,
    last_iteration: Option<i64>,
    last_time: Option<i64>,
    /// Main frames: time (µs) and values, per field.
    main_t: Vec<i64>,
    main: Vec<Vec<i64>>,
    slow_t: Vec<i64>,
    slow: Vec<Vec<i64>>,
    gps_t: Vec<i64>,
    gps: Vec<Vec<i64>>,
    last_slow: Vec<i64>,
}

/// What the frame at the reader was.
enum Frame {
    /// A frame decoded (or skipped) and stored.
    Done,
    /// The log's end: the `End of log` event or erased flash.
    End,
}

fn read_one(bytes: &[u8], start: usize, end: usize, opts: &ReadOptions) -> Result<Log> {
    let data = &bytes[..end];
    let (h, hlen) = header::parse(&data[start..], start)?;
    let ix = |name: &str| h.i.names.iter().position(|n| n == name);
    let (Some(time_ix), Some(iter_ix)) = (ix("time"), ix("loopIteration")) else {
        return Err(corrupt(
            start,
            "I fields \"time\" and \"loopIteration\"",
            "a header without them",
        ));
    };
    let mut st = State {
        h: &h,
        time_ix,
        iter_ix,
        motor0_ix: ix("motor[0]"),
        prev: None,
        prev2: None,
        home: Vec::new(),
        last_iteration: None,
        last_time: None,
        main_t: Vec::new(),
        main: vec![Vec::new(); h.i.names.len()],
        slow_t: Vec::new(),
        slow: vec![Vec::new(); h.s.names.len()],
        gps_t: Vec::new(),
        gps: vec![Vec::new(); h.g.names.len()],
        last_slow: Vec::new(),
    };
    let mut r = Reader {
        bytes: data,
        pos: start + hlen,
    };
    let mut issues = Vec::new();
    let mut ended = false;
    while r.pos < data.len() {
        let at = r.pos;
        match st.frame(&mut r) {
            Ok(Frame::Done) => {}
            Ok(Frame::End) => {
                ended = true;
                break;
            }
            Err(e) if opts.salvage => {
                let truncated = matches!(e, LogError::Truncated { .. });
                // Go on at the next intra frame (a P frame needs its predecessors).
                let next = (at + 1..data.len()).find(|&p| data[p] == b'I');
                issues.push(Issue {
                    offset: at as u64,
                    text: match (truncated, next) {
                        (false, Some(p)) => format!("{e}; skipped to the intra frame at byte {p}"),
                        _ => format!("{e}; the log is kept up to here"),
                    },
                });
                match (truncated, next) {
                    (false, Some(p)) => {
                        r.pos = p;
                        st.prev = None;
                        st.prev2 = None;
                    }
                    _ => break,
                }
            }
            Err(e) => return Err(e),
        }
    }
    if !ended && issues.is_empty() {
        // The firmware closes every log it finishes with this event; a log
        // without it lost its tail (power cut, full card, copy cut short).
        let e = LogError::Truncated {
            format: FORMAT,
            offset: r.pos as u64,
            expected: "the \"End of log\" event (or erased flash, 0xFF) closing the log".into(),
            len: data.len() as u64,
        };
        if !opts.salvage {
            return Err(e);
        }
        issues.push(Issue {
            offset: r.pos as u64,
            text: format!("{e}; the frames before it are kept"),
        });
    }
    Ok(st.into_log(start, issues))
}

impl State<'_> {
    /// Decodes the frame at the reader.
    fn frame(&mut self, r: &mut Reader) -> Result<Frame> {
        let at = r.pos;
        let marker = r.bytes[at];
        r.pos += 1;
        match marker {
            b'I' | b'P' => self.main_frame(r, at, marker == b'I')?,
            b'S' => {
                let v = self.plain_frame(r, at, 'S')?;
                self.last_slow.clone_from(&v);
                self.slow_t.push(self.last_time.unwrap_or(0));
                push_columns(&mut self.slow, &v);
            }
            b'H' => self.home = self.plain_frame(r, at, 'H')?,
            b'G' => {
                let v = self.plain_frame(r, at, 'G')?;
                let t = self.h.g.names.iter().position(|n| n == "time");
                self.gps_t.push(
                    t.and_then(|k| v.get(k).copied())
                        .unwrap_or(self.last_time.unwrap_or(0)),
                );
                push_columns(&mut self.gps, &v);
            }
            b'E' => {
                if self.event(r, at)? {
                    return Ok(Frame::End);
                }
            }
            0xff if r.bytes[at..].iter().all(|&b| b == 0xff) => return Ok(Frame::End),
            _ => {
                return Err(corrupt(
                    at,
                    "a frame marker (I, P, S, G, H or E)",
                    format!("byte 0x{marker:02X}"),
                ));
            }
        }
        // The next byte must start a frame (or the data ends): the
        // firmware's own decoder takes anything else as a corrupt frame.
        if let Some(&b) = r.bytes.get(r.pos)
            && !matches!(b, b'I' | b'P' | b'S' | b'G' | b'H' | b'E' | 0xff)
        {
            return Err(corrupt(
                r.pos,
                &format!(
                    "a frame marker after the {} frame at byte {at}",
                    marker as char
                ),
                format!("byte 0x{b:02X}"),
            ));
        }
        Ok(Frame::Done)
    }

    /// Reads the raw values of a frame with definition `def`.
    fn raw(&self, r: &mut Reader, at: usize, def: &FrameDef, kind: char) -> Result<Vec<i64>> {
        let n = def.encodings.len();
        let mut out = Vec::with_capacity(n);
        let mut i = 0;
        while i < n {
            let enc = def.encodings[i];
            let group = def.encodings[i..].iter().take_while(|&&e| e == enc).count();
            let covered = r.values(enc, n - i, group, &mut out).map_err(|s| match s {
                Stop::End => LogError::Truncated {
                    format: FORMAT,
                    offset: at as u64,
                    expected: format!(
                        "the rest of the {kind} frame (field \"{}\")",
                        def.names.get(i).map_or("?", |s| s.as_str())
                    ),
                    len: r.bytes.len() as u64,
                },
                Stop::LongVarint(p) => corrupt(
                    p,
                    "a variable-byte integer of at most 5 bytes",
                    "a longer one",
                ),
            })?;
            i += covered;
        }
        out.truncate(n);
        Ok(out)
    }

    /// An S, G or H frame: values with the predictors that need no history.
    fn plain_frame(&mut self, r: &mut Reader, at: usize, kind: char) -> Result<Vec<i64>> {
        let def = match kind {
            'S' => &self.h.s,
            'G' => &self.h.g,
            _ => &self.h.h,
        };
        if def.encodings.is_empty() {
            return Err(corrupt(
                at,
                &format!("a frame type the header defines ({kind} has no fields)"),
                format!("a {kind} frame"),
            ));
        }
        let mut v = self.raw(r, at, def, kind)?;
        let mut home_k = 0;
        for (i, x) in v.iter_mut().enumerate() {
            match def.predictors[i] {
                Predictor::HomeCoord => {
                    *x += self.home.get(home_k).copied().unwrap_or(0);
                    home_k += 1;
                }
                Predictor::LastMainFrameTime => *x += self.last_time.unwrap_or(0),
                p => *x = self.constant_prediction(p, *x, &[]),
            }
            *x = wrap(*x, def.signed.get(i).copied().unwrap_or(false));
        }
        Ok(v)
    }

    /// Predictions from header constants (the history-free predictors).
    fn constant_prediction(&self, p: Predictor, x: i64, current: &[i64]) -> i64 {
        match p {
            Predictor::MinThrottle => x + self.h.minthrottle,
            Predictor::MinMotor => x + self.h.motor_output[0],
            Predictor::Around1500 => x + 1500,
            Predictor::VbatRef => x + self.h.vbatref,
            Predictor::Motor0 => {
                x + self
                    .motor0_ix
                    .and_then(|k| current.get(k))
                    .copied()
                    .unwrap_or(0)
            }
            _ => x,
        }
    }

    /// An I or P frame.
    fn main_frame(&mut self, r: &mut Reader, at: usize, intra: bool) -> Result<()> {
        let h = self.h;
        let def = if intra { &h.i } else { &h.p };
        let raw = self.raw(r, at, def, if intra { 'I' } else { 'P' })?;
        if !intra && self.prev.is_none() {
            return Err(corrupt(
                at,
                "an I frame before the first P frame (P frames are differences)",
                "a P frame",
            ));
        }
        let skipped = if intra { 0 } else { self.skipped_frames() };
        let mut cur = Vec::with_capacity(raw.len());
        for (i, &x) in raw.iter().enumerate() {
            let prev = self.prev.as_ref().and_then(|p| p.get(i)).copied();
            let prev2 = self.prev2.as_ref().and_then(|p| p.get(i)).copied();
            let signed = h.i.signed.get(i).copied().unwrap_or(false);
            let v = match (def.predictors[i], prev, prev2) {
                (Predictor::Previous, Some(a), _) => x + a,
                (Predictor::StraightLine, Some(a), Some(b)) => x + 2 * a - b,
                (Predictor::Average2, Some(a), Some(b)) => x + (a + b) / 2,
                (Predictor::Increment, a, _) => skipped + 1 + a.unwrap_or(0),
                (p, _, _) => self.constant_prediction(p, x, &cur),
            };
            cur.push(wrap(v, signed));
        }
        let time = cur[self.time_ix];
        let iteration = cur[self.iter_ix];
        if let (Some(t0), Some(i0)) = (self.last_time, self.last_iteration) {
            if !(time >= t0 && time - t0 <= MAX_TIME_JUMP_US) {
                return Err(corrupt(
                    at,
                    &format!("a frame time from {t0} µs to {} µs", t0 + MAX_TIME_JUMP_US),
                    format!("{time} µs"),
                ));
            }
            if !(iteration >= i0 && iteration - i0 <= MAX_ITERATION_JUMP) {
                return Err(corrupt(
                    at,
                    &format!("a loop iteration from {i0} to {}", i0 + MAX_ITERATION_JUMP),
                    iteration.to_string(),
                ));
            }
        }
        self.last_time = Some(time);
        self.last_iteration = Some(iteration);
        self.main_t.push(time);
        push_columns(&mut self.main, &cur);
        self.prev2 = if intra {
            Some(cur.clone())
        } else {
            self.prev.take()
        };
        self.prev = Some(cur);
        Ok(())
    }

    /// Loop iterations the logging rate skips after the last main frame.
    fn skipped_frames(&self) -> i64 {
        let Some(last) = self.last_iteration else {
            return 0;
        };
        let (i_int, num, den) = (
            i64::from(self.h.i_interval),
            i64::from(self.h.p_num),
            i64::from(self.h.p_denom),
        );
        let logged = |k: i64| (k % i_int + num - 1) % den < num;
        let mut count = 0;
        let mut k = last + 1;
        // At most `den - 1` iterations lie between two logged ones; the cap
        // bounds the loop for a damaged header too.
        while !logged(k) && count < den.min(1 << 16) {
            count += 1;
            k += 1;
        }
        count
    }

    /// An event frame; `true` at the end of the log.
    fn event(&mut self, r: &mut Reader, at: usize) -> Result<bool> {
        let trunc = |r: &Reader| LogError::Truncated {
            format: FORMAT,
            offset: at as u64,
            expected: "the rest of the event frame".into(),
            len: r.bytes.len() as u64,
        };
        let long = |_| {
            corrupt(
                at,
                "an event frame with variable-byte integers of at most 5 bytes",
                "a longer one",
            )
        };
        let map = |s: Stop, r: &Reader| match s {
            Stop::End => trunc(r),
            Stop::LongVarint(p) => long(p),
        };
        let code = r.byte().map_err(|s| map(s, r))?;
        let n_varints = match code {
            0 | 15 | 40 => 1,
            14 | 30 => 2,
            13 => {
                let f = r.byte().map_err(|s| map(s, r))?;
                if f & 0x80 != 0 {
                    for _ in 0..4 {
                        r.byte().map_err(|s| map(s, r))?;
                    }
                    0
                } else {
                    1
                }
            }
            255 => {
                const END: &[u8] = b"End of log\0";
                let rest = &r.bytes[r.pos..];
                if rest.len() < END.len() && END.starts_with(rest) {
                    return Err(trunc(r));
                }
                if !rest.starts_with(END) {
                    return Err(corrupt(
                        r.pos,
                        "\"End of log\" and a NUL byte after event 255",
                        "other bytes",
                    ));
                }
                r.pos += END.len();
                return Ok(true);
            }
            c => {
                return Err(corrupt(
                    at + 1,
                    "an event code (0, 13, 14, 15, 30, 40 or 255)",
                    c.to_string(),
                ));
            }
        };
        for _ in 0..n_varints {
            r.unsigned_vb().map_err(|s| map(s, r))?;
        }
        if code == 14 {
            // Logging resumed: the next frame is an I frame; the clock may jump.
            self.prev = None;
            self.prev2 = None;
            self.last_time = None;
            self.last_iteration = None;
        }
        Ok(false)
    }

    fn into_log(self, start: usize, issues: Vec<Issue>) -> Log {
        let h = self.h;
        let secs = |t: &[i64]| t.iter().map(|&x| x as f64 * 1e-6).collect::<Vec<f64>>();
        let mut topics = vec![Topic {
            name: "main".into(),
            t: secs(&self.main_t),
            fields: h
                .i
                .names
                .iter()
                .zip(self.main)
                .enumerate()
                .filter(|(k, _)| *k != self.time_ix)
                .map(|(_, (name, v))| main_field(h, name, &v))
                .collect(),
        }];
        for (name, def, t, cols) in [
            ("slow", &h.s, self.slow_t, self.slow),
            ("gps", &h.g, self.gps_t, self.gps),
        ] {
            if !t.is_empty() {
                let mut topic = Topic {
                    name: name.into(),
                    t: secs(&t),
                    fields: def
                        .names
                        .iter()
                        .zip(cols)
                        .map(|(n, v)| Field {
                            name: n.clone(),
                            unit: Unit::Raw,
                            range: None,
                            values: v.iter().map(|&x| x as f64).collect(),
                        })
                        .collect(),
                };
                topic.sort_by_time();
                topics.push(topic);
            }
        }
        Log {
            format: FORMAT,
            offset: start as u64,
            topics,
            info: h.lines.clone(),
            issues,
        }
    }
}

/// A main-frame field in its unit: gyro in rad/s (`gyro_scale` deg/s per
/// unit, Baseflight: rad/µs), rate setpoints in rad/s, accelerometer in g,
/// motor commands raw with the header's `motorOutput` range.
fn main_field(h: &Header, name: &str, v: &[i64]) -> Field {
    let gyro = if h.firmware_type == "Baseflight" {
        h.gyro_scale * 1e6
    } else {
        h.gyro_scale.to_radians()
    };
    let (unit, scale, range) = if name.starts_with("gyroADC[") || name.starts_with("gyroUnfilt[") {
        (Unit::RadPerSecond, gyro, None)
    } else if ["setpoint[0]", "setpoint[1]", "setpoint[2]"].contains(&name) {
        (Unit::RadPerSecond, 1f64.to_radians(), None)
    } else if name.starts_with("accSmooth[") {
        (Unit::StandardGravity, 1.0 / h.acc_1g, None)
    } else if name.starts_with("motor[") {
        let [lo, hi] = h.motor_output;
        (Unit::Raw, 1.0, (hi > lo).then_some([lo as f64, hi as f64]))
    } else {
        (Unit::Raw, 1.0, None)
    };
    Field {
        name: name.to_string(),
        unit,
        range,
        values: v.iter().map(|&x| x as f64 * scale).collect(),
    }
}

/// `v` as the firmware's 32-bit integer of that signedness.
fn wrap(v: i64, signed: bool) -> i64 {
    if signed {
        i64::from(v as i32)
    } else {
        i64::from(v as u32)
    }
}

fn push_columns(cols: &mut [Vec<i64>], v: &[i64]) {
    for (c, x) in cols.iter_mut().zip(v) {
        c.push(*x);
    }
}
