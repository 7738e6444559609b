//! The numbers of the header's encodings and predictors, and the error
//! every part of the decoder reports damage with.

use crate::error::LogError;
use crate::model::LogFormat;

pub(crate) const FORMAT: LogFormat = LogFormat::Betaflight;

/// A field encoding (the numbers of the `Field X encoding` header lines).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Encoding {
    SignedVb,
    UnsignedVb,
    Neg14Bit,
    Tag8_8Svb,
    Tag2_3S32,
    Tag8_4S16,
    Null,
    Tag2_3SVariable,
}

impl Encoding {
    pub(crate) fn from_number(s: &str) -> Option<Encoding> {
        Some(match s.parse::<u8>().ok()? {
            0 => Encoding::SignedVb,
            1 => Encoding::UnsignedVb,
            3 => Encoding::Neg14Bit,
            6 => Encoding::Tag8_8Svb,
            7 => Encoding::Tag2_3S32,
            8 => Encoding::Tag8_4S16,
            9 => Encoding::Null,
            10 => Encoding::Tag2_3SVariable,
            _ => return None,
        })
    }
}

/// A field predictor (the numbers of the `Field X predictor` lines).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Predictor {
    Zero,
    Previous,
    StraightLine,
    Average2,
    MinThrottle,
    Motor0,
    Increment,
    HomeCoord,
    Around1500,
    VbatRef,
    LastMainFrameTime,
    MinMotor,
}

impl Predictor {
    pub(crate) fn from_number(s: &str) -> Option<Predictor> {
        Some(match s.parse::<u8>().ok()? {
            0 => Predictor::Zero,
            1 => Predictor::Previous,
            2 => Predictor::StraightLine,
            3 => Predictor::Average2,
            4 => Predictor::MinThrottle,
            5 => Predictor::Motor0,
            6 => Predictor::Increment,
            7 => Predictor::HomeCoord,
            8 => Predictor::Around1500,
            9 => Predictor::VbatRef,
            10 => Predictor::LastMainFrameTime,
            11 => Predictor::MinMotor,
            _ => return None,
        })
    }
}

pub(crate) fn corrupt(offset: usize, expected: &str, found: impl Into<String>) -> LogError {
    LogError::Corrupt {
        format: FORMAT,
        offset: offset as u64,
        expected: expected.to_string(),
        found: found.into(),
    }
}
