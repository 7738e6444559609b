//! The 16-bit coefficient rows of the Kalman filter and the fast
//! gradient's `M` matrix.

use crate::firmware::design::FirmwareDesign;
use crate::firmware::error::DesignError;

/// One coefficient row quantised to `i16` with its binary point: the
/// largest shift (at most 40) that keeps the row's largest entry within
/// 16 bits, and the first non-zero column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct QuantRow {
    /// Coefficients, `value = c / 2^shift`.
    pub c: Vec<i16>,
    /// Fraction bits.
    pub shift: u8,
    /// First non-zero column (the row's length if all are zero).
    pub start: usize,
}

/// Quantises a row (see [`QuantRow`]); `None` if a value is not finite.
pub fn quantize_row(row: &[f64]) -> Option<QuantRow> {
    if row.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let max = row.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut shift: i32 = 40;
    while shift > -15 && (max * 2f64.powi(shift)).round() > 32767.0 {
        shift -= 1;
    }
    if shift < 0 {
        return None; // |v| >= 2^15: not a Q15.16 coefficient
    }
    let c: Vec<i16> = row
        .iter()
        .map(|v| (v * 2f64.powi(shift)).round() as i16)
        .collect();
    let start = c.iter().position(|v| *v != 0).unwrap_or(c.len());
    Some(QuantRow {
        c,
        shift: shift as u8,
        start,
    })
}

/// The Kalman filter's rows for [`kestrel_avr_rt::kalman16::Kalman16`]: `C`, `M`,
/// `A - I` and `B`, each row quantised with its own binary point.
#[derive(Clone, Debug, PartialEq)]
pub struct Kalman16Design {
    /// Rows of `C`.
    pub c: Vec<QuantRow>,
    /// `y0` in Q15.16.
    pub y0: Vec<i32>,
    /// Rows of `M`.
    pub m: Vec<QuantRow>,
    /// Rows of `A - I`.
    pub a: Vec<QuantRow>,
    /// Rows of `B`.
    pub b: Vec<QuantRow>,
}

impl FirmwareDesign {
    /// The rows of the fast gradient's `M` in Q1.15 for
    /// [`kestrel_avr_rt::fgm16::Fgm16Law`] (entries of 1 saturate to `1 - 2^-15`).
    ///
    /// # Errors
    /// [`DesignError::Unsupported`] if an entry is outside `[-1, 1]`.
    pub fn fgm16_m(&self) -> Result<Vec<QuantRow>, DesignError> {
        let n = self.data_f64.n;
        let shift = kestrel_avr_rt::fgm16::M_SHIFT;
        let scale = 2f64.powi(shift as i32);
        self.data_f64
            .m
            .chunks(n.max(1))
            .map(|r| {
                if r.iter().any(|v| !v.is_finite() || v.abs() > 1.0 + 1e-9) {
                    return Err(DesignError::Unsupported(
                        "a fast-gradient M entry is outside [-1, 1]".into(),
                    ));
                }
                let c: Vec<i16> = r
                    .iter()
                    .map(|v| (v * scale).round().clamp(-32768.0, 32767.0) as i16)
                    .collect();
                let start = c.iter().position(|v| *v != 0).unwrap_or(c.len());
                Ok(QuantRow { c, shift, start })
            })
            .collect()
    }

    /// The momentum table in Q1.15 (`round(beta 2^15)`, at most 32767).
    pub fn fgm16_betas(&self) -> Vec<i16> {
        self.data_f64
            .betas
            .iter()
            .map(|b| (b * 32768.0).round().clamp(-32768.0, 32767.0) as i16)
            .collect()
    }

    /// The filter quantised for [`kestrel_avr_rt::kalman16::Kalman16`].
    ///
    /// # Errors
    /// [`DesignError::Unsupported`] if a coefficient is 2^15 or larger.
    pub fn kalman16(&self) -> Result<Kalman16Design, DesignError> {
        let k = &self.kalman;
        let nx = k.nx();
        let big = || DesignError::Unsupported("a Kalman coefficient does not fit Q15.16".into());
        let rows = |m: &nalgebra::DMatrix<f64>| -> Result<Vec<QuantRow>, DesignError> {
            (0..m.nrows())
                .map(|i| {
                    let r: Vec<f64> = m.row(i).iter().copied().collect();
                    quantize_row(&r).ok_or_else(big)
                })
                .collect()
        };
        let y0 =
            k.y0.iter()
                .map(|v| {
                    let q = (v * 65536.0).round();
                    if q.abs() < 2f64.powi(31) {
                        Ok(q as i32)
                    } else {
                        Err(big())
                    }
                })
                .collect::<Result<_, _>>()?;
        Ok(Kalman16Design {
            c: rows(&k.c)?,
            y0,
            m: rows(&k.filter.m)?,
            a: rows(&(&k.a - nalgebra::DMatrix::identity(nx, nx)))?,
            b: rows(&k.b)?,
        })
    }
}
