//! Every signal scaled to unit variance, as N4SID and PEM work inside.

use crate::data::IoData;
use crate::error::Result;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};

/// Input and output scaling used internally (each signal to unit variance).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Scaling {
    /// Factor of every input.
    pub su: DVector<f64>,
    /// Factor of every output.
    pub sy: DVector<f64>,
}

impl Scaling {
    /// The factors `1 / std` of the signals of `data` (an error when a
    /// signal is constant).
    pub fn of(data: &IoData) -> Result<Self> {
        let (su, sy) = data.check_excitation()?;
        Ok(Scaling {
            su: su.map(|s| 1.0 / s),
            sy: sy.map(|s| 1.0 / s),
        })
    }
    /// Model of the scaled data -> model of the original data.
    pub fn unscale(&self, m: &InnovationModel) -> InnovationModel {
        let su = DMatrix::from_diagonal(&self.su);
        let sy = DMatrix::from_diagonal(&self.sy);
        let syi = DMatrix::from_diagonal(&self.sy.map(|s| 1.0 / s));
        InnovationModel {
            ts: m.ts,
            a: m.a.clone(),
            b: &m.b * &su,
            c: &syi * &m.c,
            d: &syi * &m.d * &su,
            k: &m.k * &sy,
        }
    }
    /// Model of the original data -> model of the scaled data.
    pub fn scale(&self, m: &InnovationModel) -> InnovationModel {
        let inv = Scaling {
            su: self.su.map(|s| 1.0 / s),
            sy: self.sy.map(|s| 1.0 / s),
        };
        inv.unscale(m)
    }
}
