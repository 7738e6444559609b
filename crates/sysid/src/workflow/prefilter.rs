//! The vibration pre-filter chosen from the periodogram: [`Prefilter`]
//! and [`choose_prefilter`].

use crate::data::IoData;
use crate::filter::periodogram;

/// The pre-filter of [`IdentifySpec::prefilter`](super::IdentifySpec::prefilter).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Prefilter {
    /// No pre-filter (the default; [`IdentifySpec::lowpass`](super::IdentifySpec::lowpass) still applies).
    #[default]
    None,
    /// Chosen by [`choose_prefilter`] from the outputs' periodogram on the
    /// estimation data.
    Auto,
}

/// What [`choose_prefilter`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrefilterChoice {
    /// Frequency of the vibration peak in rad/s.
    pub peak: f64,
    /// Its power over the median power of the upper four fifths of the
    /// band (of the output where the ratio is largest).
    pub ratio: f64,
    /// The low-pass cut-off in rad/s (`None`: no narrow peak, no filter).
    pub cutoff: Option<f64>,
}

/// Looks for motor vibration in the outputs of `est` (Welch periodogram,
/// segments of up to 256 samples): the largest peak above a fifth of the
/// Nyquist frequency, against the median power there. A peak at least
/// 20 times the median gives a low-pass cut-off at 0.6 times the peak
/// frequency (at least a fifth of Nyquist), otherwise none. `None` when
/// the record is too short for a periodogram.
pub fn choose_prefilter(est: &IoData) -> Option<PrefilterChoice> {
    let n = est.experiments().iter().map(|e| e.len()).max()?;
    let segment = (n / 4).next_power_of_two().min(256) / 2 * 2;
    let segment = if segment > n / 2 {
        segment / 2
    } else {
        segment
    };
    if segment < 16 {
        return None;
    }
    let e = est.experiments().iter().max_by_key(|e| e.len())?;
    let nyquist = std::f64::consts::PI / est.ts();
    let mut best: Option<(f64, f64)> = None;
    for j in 0..est.ny() {
        let x: Vec<f64> = e.y.column(j).iter().copied().collect();
        let Ok(p) = periodogram(&x, est.ts(), segment) else {
            continue;
        };
        let band: Vec<(f64, f64)> = p
            .omega
            .iter()
            .zip(&p.power)
            .filter(|(w, _)| **w >= 0.2 * nyquist)
            .map(|(w, v)| (*w, *v))
            .collect();
        let mut powers: Vec<f64> = band.iter().map(|b| b.1).collect();
        powers.sort_by(f64::total_cmp);
        let Some(&median) = powers.get(powers.len() / 2) else {
            continue;
        };
        let Some(&(w, v)) = band.iter().max_by(|a, b| a.1.total_cmp(&b.1)) else {
            continue;
        };
        let ratio = if median > 0.0 { v / median } else { 0.0 };
        if best.is_none_or(|(_, r)| ratio > r) {
            best = Some((w, ratio));
        }
    }
    let (peak, ratio) = best?;
    let cutoff = (ratio >= 20.0).then(|| (0.6 * peak).max(0.2 * nyquist));
    Some(PrefilterChoice {
        peak,
        ratio,
        cutoff,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// A 150 Hz tone on a slow signal with white noise sampled at 500 Hz
    /// is found and cut below it; the slow signal alone gives no filter.
    #[test]
    fn a_vibration_tone_is_found() {
        let ts = 0.002;
        let n = 4000;
        let mut rng = crate::synthetic::Rng::new(1);
        let noise: Vec<f64> = (0..n + 7).map(|_| 0.05 * rng.normal()).collect();
        let slow =
            |t: usize| (t as f64 * ts * 3.0).sin() + 0.3 * (t as f64 * ts * 11.0).cos() + noise[t];
        let u = DMatrix::from_fn(n, 1, |t, _| slow(t + 7));
        let tone = DMatrix::from_fn(n, 1, |t, _| {
            slow(t) + 0.5 * (2.0 * std::f64::consts::PI * 150.0 * t as f64 * ts).sin()
        });
        let d = IoData::new(ts, u.clone(), tone).unwrap();
        let c = choose_prefilter(&d).unwrap();
        let hz = c.peak / (2.0 * std::f64::consts::PI);
        assert!((hz - 150.0).abs() < 3.0, "{hz}");
        let cut = c.cutoff.unwrap();
        assert!(cut < c.peak && cut >= 0.2 * std::f64::consts::PI / ts);
        let clean = IoData::new(ts, u, DMatrix::from_fn(n, 1, |t, _| slow(t))).unwrap();
        assert!(choose_prefilter(&clean).unwrap().cutoff.is_none());
    }
}
