//! The text header of a Betaflight blackbox log: `H name:value` lines.

use super::defs::{Encoding, Predictor, corrupt};
use crate::error::Result;

/// The field definitions of one frame type.
#[derive(Clone, Debug, Default)]
pub(crate) struct FrameDef {
    pub names: Vec<String>,
    pub signed: Vec<bool>,
    pub predictors: Vec<Predictor>,
    pub encodings: Vec<Encoding>,
}

/// What the decoder needs from the header.
#[derive(Clone, Debug, Default)]
pub(crate) struct Header {
    pub i: FrameDef,
    pub p: FrameDef,
    pub s: FrameDef,
    pub g: FrameDef,
    pub h: FrameDef,
    pub data_version: u32,
    pub i_interval: u32,
    pub p_num: u32,
    pub p_denom: u32,
    pub minthrottle: i64,
    pub motor_output: [i64; 2],
    pub vbatref: i64,
    pub gyro_scale: f64,
    pub acc_1g: f64,
    pub firmware_type: String,
    /// Every header line, `(name, value)`, for [`crate::Log::info`].
    pub lines: Vec<(String, String)>,
}

fn list<T>(
    value: &str,
    at: usize,
    what: &str,
    parse: impl Fn(&str) -> Option<T>,
) -> Result<Vec<T>> {
    value
        .split(',')
        .map(|s| {
            parse(s.trim()).ok_or_else(|| {
                corrupt(
                    at,
                    &format!("a list of {what}"),
                    format!("\"{}\"", value.trim()),
                )
            })
        })
        .collect()
}

fn int(value: &str, at: usize, what: &str) -> Result<i64> {
    value.trim().parse::<i64>().map_err(|_| {
        corrupt(
            at,
            &format!("{what} (an integer)"),
            format!("\"{}\"", value.trim()),
        )
    })
}

/// Parses the header at the start of `bytes` (offsets relative to `base`);
/// returns it and the offset of the first data byte.
pub(crate) fn parse(bytes: &[u8], base: usize) -> Result<(Header, usize)> {
    let mut h = Header {
        i_interval: 32,
        p_num: 1,
        p_denom: 1,
        data_version: 2,
        gyro_scale: 1.0,
        acc_1g: 1.0,
        ..Default::default()
    };
    let mut pos = 0;
    while bytes.get(pos) == Some(&b'H') && bytes.get(pos + 1) == Some(&b' ') {
        let at = base + pos;
        let Some(n) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(crate::error::LogError::Truncated {
                format: crate::model::LogFormat::Betaflight,
                offset: at as u64,
                expected: "a header line ended by a newline".into(),
                len: (base + bytes.len()) as u64,
            });
        };
        let line = std::str::from_utf8(&bytes[pos + 2..pos + n])
            .map_err(|_| corrupt(at, "a header line of text", "bytes that are not UTF-8"))?;
        let (key, value) = line
            .split_once(':')
            .ok_or_else(|| corrupt(at, "a header line \"H name:value\"", format!("\"{line}\"")))?;
        apply(&mut h, key, value, at)?;
        h.lines.push((key.to_string(), value.to_string()));
        pos += n + 1;
    }
    check(&h, base + pos)?;
    Ok((h, pos))
}

fn apply(h: &mut Header, key: &str, value: &str, at: usize) -> Result<()> {
    let flags = |v: &str| list(v, at, "0/1 flags", |s| s.parse::<u8>().ok().map(|x| x != 0));
    let preds = |v: &str| list(v, at, "predictor numbers (0..11)", Predictor::from_number);
    let encs = |v: &str| {
        list(
            v,
            at,
            "encoding numbers (0, 1, 3, 6, 7, 8, 9, 10)",
            Encoding::from_number,
        )
    };
    if let Some(rest) = key.strip_prefix("Field ") {
        let (frame, what) = rest
            .split_once(' ')
            .ok_or_else(|| corrupt(at, "\"Field X what\"", format!("\"{key}\"")))?;
        let def = match frame {
            "I" => &mut h.i,
            "P" => &mut h.p,
            "S" => &mut h.s,
            "G" => &mut h.g,
            "H" => &mut h.h,
            _ => return Ok(()),
        };
        match what {
            "name" => def.names = value.split(',').map(|s| s.trim().to_string()).collect(),
            "signed" => def.signed = flags(value)?,
            "predictor" => def.predictors = preds(value)?,
            "encoding" => def.encodings = encs(value)?,
            _ => {}
        }
        return Ok(());
    }
    match key {
        "Data version" => h.data_version = int(value, at, "the data version")? as u32,
        "I interval" => h.i_interval = int(value, at, "the I interval")?.max(1) as u32,
        "P interval" => match value.split_once('/') {
            Some((a, b)) => {
                h.p_num = int(a, at, "the P interval numerator")?.max(1) as u32;
                h.p_denom = int(b, at, "the P interval denominator")?.max(1) as u32;
            }
            None => {
                h.p_num = 1;
                h.p_denom = int(value, at, "the P interval")?.max(1) as u32;
            }
        },
        "minthrottle" => h.minthrottle = int(value, at, "minthrottle")?,
        "motorOutput" => {
            let v = list(value, at, "integers", |s| s.parse::<i64>().ok())?;
            h.motor_output = [
                v.first().copied().unwrap_or(0),
                v.get(1).copied().unwrap_or(0),
            ];
        }
        "vbatref" => h.vbatref = int(value, at, "vbatref")?,
        "acc_1G" => h.acc_1g = int(value, at, "acc_1G")? as f64,
        "gyro_scale" | "gyro.scale" => {
            let hex = value.trim().trim_start_matches("0x");
            let bits = u32::from_str_radix(hex, 16).map_err(|_| {
                corrupt(
                    at,
                    "gyro_scale as 0x followed by 8 hex digits",
                    format!("\"{value}\""),
                )
            })?;
            h.gyro_scale = f64::from(f32::from_bits(bits));
        }
        "Firmware type" => h.firmware_type = value.trim().to_string(),
        _ => {}
    }
    Ok(())
}

/// The definitions are complete and consistent.
fn check(h: &Header, end: usize) -> Result<()> {
    let i = &h.i;
    let n = i.names.len();
    if n == 0 {
        return Err(corrupt(
            end,
            "a \"Field I name\" header line before the first frame",
            "none",
        ));
    }
    for (what, len) in [
        ("Field I predictor", i.predictors.len()),
        ("Field I encoding", i.encodings.len()),
        ("Field P predictor", h.p.predictors.len()),
        ("Field P encoding", h.p.encodings.len()),
    ] {
        if len != n {
            return Err(corrupt(
                end,
                &format!("a \"{what}\" line with {n} entries, one per I field (header ends here)"),
                format!("{len} entries"),
            ));
        }
    }
    for name in ["time", "loopIteration"] {
        if !i.names.iter().any(|x| x == name) {
            return Err(corrupt(
                end,
                &format!("an I field named \"{name}\" (header ends here)"),
                "none",
            ));
        }
    }
    for (label, def) in [("S", &h.s), ("G", &h.g), ("H", &h.h)] {
        let m = def.names.len();
        if def.encodings.len() != m || def.predictors.len() != m {
            return Err(corrupt(
                end,
                &format!(
                    "\"Field {label} predictor\" and \"encoding\" lines with {m} entries each (header ends here)"
                ),
                format!("{} and {}", def.predictors.len(), def.encodings.len()),
            ));
        }
    }
    Ok(())
}
