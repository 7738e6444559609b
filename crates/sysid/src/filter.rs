//! Butterworth low-pass filters by the bilinear transform with
//! pre-warping (thesis (5.7)-(5.9)), zero-phase forward-backward filtering,
//! and a Welch periodogram for choosing the cut-off.

use crate::error::{Result, SysidError};
use nalgebra::Complex;

/// One second-order section `H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad {
    /// Numerator `[b0, b1, b2]`.
    pub b: [f64; 3],
    /// Denominator `[a1, a2]` (`a0 = 1`).
    pub a: [f64; 2],
}

impl Biquad {
    /// Gain at `z = 1`.
    pub fn dc_gain(&self) -> f64 {
        (self.b[0] + self.b[1] + self.b[2]) / (1.0 + self.a[0] + self.a[1])
    }

    /// Response at `z`.
    pub fn response(&self, z: Complex<f64>) -> Complex<f64> {
        let zi = z.inv();
        let num = self.b[0] + zi * (self.b[1] + zi * self.b[2]);
        let den = 1.0 + zi * (self.a[0] + zi * self.a[1]);
        num / den
    }

    /// Filters `x` in place (transposed direct form II) from state `s`.
    fn run(&self, x: &mut [f64], mut s: [f64; 2]) {
        for v in x.iter_mut() {
            let xin = *v;
            let y = self.b[0] * xin + s[0];
            s[0] = self.b[1] * xin - self.a[0] * y + s[1];
            s[1] = self.b[2] * xin - self.a[1] * y;
            *v = y;
        }
    }

    /// The state for which a constant input `c` gives a constant output.
    fn steady_state(&self, c: f64) -> [f64; 2] {
        let g = self.dc_gain();
        let s1 = (self.b[2] - self.a[1] * g) * c;
        let s0 = (self.b[1] - self.a[0] * g) * c + s1;
        [s0, s1]
    }
}

/// A discrete Butterworth low-pass filter as a cascade of second-order sections.
///
/// Designed from the analog Butterworth prototype of the given order with
/// the bilinear transform `s = gamma (z - 1)/(z + 1)`. As in (5.9) of the
/// thesis, `gamma` is chosen so the analog cut-off maps exactly onto the
/// wanted discrete one: `omega_c = gamma tan(omega_d T / 2)`. We take
/// `gamma = 2/T` and pre-warp the analog cut-off to
/// `omega_a = (2/T) tan(omega_d T / 2)`, which is the same thing. The
/// -3 dB point of `|H(e^{j omega_d T})|` is then exactly `omega_d`.
///
/// ```
/// use kestrel_sysid::Butterworth;
/// // The thesis's filter: 20 rad/s at 50 Hz.
/// let f = Butterworth::design(2, 20.0, 0.02).unwrap();
/// assert!((f.gain(20.0) - 0.5f64.sqrt()).abs() < 1e-12);
/// assert!((f.gain(0.0) - 1.0).abs() < 1e-12);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Butterworth {
    order: usize,
    cutoff: f64,
    ts: f64,
    sections: Vec<Biquad>,
}

impl Butterworth {
    /// Designs a low-pass of `order` (1..=12) with cut-off `cutoff_rad_s`
    /// (rad/s, below the Nyquist frequency `pi/ts`) for sample time `ts`.
    pub fn design(order: usize, cutoff_rad_s: f64, ts: f64) -> Result<Self> {
        if !(1..=12).contains(&order) {
            return Err(SysidError::invalid(format!(
                "Butterworth order must be 1..=12, found {order}"
            )));
        }
        if !(ts.is_finite() && ts > 0.0) {
            return Err(SysidError::invalid(format!(
                "sample time must be > 0, found {ts}"
            )));
        }
        let nyq = std::f64::consts::PI / ts;
        if !(cutoff_rad_s.is_finite() && cutoff_rad_s > 0.0 && cutoff_rad_s < nyq) {
            return Err(SysidError::invalid(format!(
                "cut-off must lie in (0, {nyq:.4}) rad/s (the Nyquist frequency), found {cutoff_rad_s}"
            )));
        }
        // Pre-warped, normalised by gamma = 2/T: kk = omega_a / gamma.
        let kk = (cutoff_rad_s * ts / 2.0).tan();
        let mut sections = Vec::new();
        for i in 0..order / 2 {
            // Analog pole pair at angle theta from the negative real axis:
            // s^2 + 2 sin(pi (2i+1)/(2n)) w s + w^2.
            let a1 = 2.0 * ((2 * i + 1) as f64 * std::f64::consts::PI / (2 * order) as f64).sin();
            let a0 = 1.0 + a1 * kk + kk * kk;
            let g = kk * kk / a0;
            sections.push(Biquad {
                b: [g, 2.0 * g, g],
                a: [(2.0 * kk * kk - 2.0) / a0, (1.0 - a1 * kk + kk * kk) / a0],
            });
        }
        if order % 2 == 1 {
            let g = kk / (1.0 + kk);
            sections.push(Biquad {
                b: [g, g, 0.0],
                a: [(kk - 1.0) / (1.0 + kk), 0.0],
            });
        }
        Ok(Butterworth {
            order,
            cutoff: cutoff_rad_s,
            ts,
            sections,
        })
    }

    /// The order.
    pub fn order(&self) -> usize {
        self.order
    }
    /// The cut-off in rad/s.
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }
    /// The second-order sections (a first-order one last for odd orders).
    pub fn sections(&self) -> &[Biquad] {
        &self.sections
    }

    /// Complex response at `omega` rad/s.
    pub fn response(&self, omega: f64) -> Complex<f64> {
        let z = Complex::from_polar(1.0, omega * self.ts);
        self.sections
            .iter()
            .fold(Complex::new(1.0, 0.0), |h, s| h * s.response(z))
    }

    /// Magnitude of the response at `omega` rad/s.
    pub fn gain(&self, omega: f64) -> f64 {
        self.response(omega).norm()
    }

    /// Causal filtering from rest at the first value (steady-state start).
    pub fn filter(&self, x: &[f64]) -> Vec<f64> {
        let mut y = x.to_vec();
        self.run_from_steady(&mut y);
        y
    }

    fn run_from_steady(&self, y: &mut [f64]) {
        let mut c = y.first().copied().unwrap_or(0.0);
        for s in &self.sections {
            let st = s.steady_state(c);
            s.run(y, st);
            c *= s.dc_gain();
        }
    }

    /// Zero-phase filtering: forward, then backward (gain `|H|^2`, no
    /// delay). The ends are extended by odd reflection and each pass starts
    /// from the steady state of its first value, which keeps start and end
    /// transients small.
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        let n = x.len();
        if n < 2 {
            return x.to_vec();
        }
        let pad = (6 * self.order + 3).min(n - 1);
        let mut ext = Vec::with_capacity(n + 2 * pad);
        for k in (1..=pad).rev() {
            ext.push(2.0 * x[0] - x[k]);
        }
        ext.extend_from_slice(x);
        for k in 1..=pad {
            ext.push(2.0 * x[n - 1] - x[n - 1 - k]);
        }
        self.run_from_steady(&mut ext);
        ext.reverse();
        self.run_from_steady(&mut ext);
        ext.reverse();
        ext[pad..pad + n].to_vec()
    }
}

/// A one-sided power spectral density estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Periodogram {
    /// Frequencies in rad/s, from 0 to the Nyquist frequency.
    pub omega: Vec<f64>,
    /// Power spectral density (signal units squared per rad/s).
    pub power: Vec<f64>,
}

impl Periodogram {
    /// The frequency (rad/s) of the largest power, ignoring zero frequency.
    pub fn peak(&self) -> Option<f64> {
        self.power
            .iter()
            .enumerate()
            .skip(1)
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(i, _)| self.omega[i])
    }
}

/// In-place radix-2 FFT (length a power of two).
fn fft(x: &mut [Complex<f64>]) {
    let n = x.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            x.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let w = Complex::from_polar(1.0, -2.0 * std::f64::consts::PI / len as f64);
        for start in (0..n).step_by(len) {
            let mut wk = Complex::new(1.0, 0.0);
            for k in 0..len / 2 {
                let a = x[start + k];
                let b = x[start + k + len / 2] * wk;
                x[start + k] = a + b;
                x[start + k + len / 2] = a - b;
                wk *= w;
            }
        }
        len <<= 1;
    }
}

/// Welch's averaged periodogram of `x` (sample time `ts`): Hann-windowed
/// segments of `segment` samples (a power of two, at most the data length)
/// with 50 % overlap, mean removed per segment. The density integrates to
/// the variance: `sum(power) * d_omega ~ var(x)`.
pub fn periodogram(x: &[f64], ts: f64, segment: usize) -> Result<Periodogram> {
    if !segment.is_power_of_two() || segment < 8 {
        return Err(SysidError::invalid(format!(
            "periodogram segment must be a power of two >= 8, found {segment}"
        )));
    }
    if x.len() < segment {
        return Err(SysidError::TooFewSamples {
            what: format!("a periodogram with segments of {segment}"),
            needed: segment,
            found: x.len(),
        });
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::invalid(
            "periodogram of a signal with NaN or infinity",
        ));
    }
    if !(ts.is_finite() && ts > 0.0) {
        return Err(SysidError::invalid("sample time must be > 0"));
    }
    let win: Vec<f64> = (0..segment)
        .map(|k| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / segment as f64).cos())
        .collect();
    let wpow: f64 = win.iter().map(|w| w * w).sum();
    let half = segment / 2;
    let mut acc = vec![0.0; half + 1];
    let mut count = 0usize;
    let mut start = 0;
    let mut buf = vec![Complex::new(0.0, 0.0); segment];
    while start + segment <= x.len() {
        let seg = &x[start..start + segment];
        let mean = seg.iter().sum::<f64>() / segment as f64;
        for k in 0..segment {
            buf[k] = Complex::new((seg[k] - mean) * win[k], 0.0);
        }
        fft(&mut buf);
        for (k, a) in acc.iter_mut().enumerate() {
            *a += buf[k].norm_sqr();
        }
        count += 1;
        start += half;
    }
    // Two-sided density in units^2 per (rad/sample) is |X|^2 / (2 pi wpow);
    // fold to one side and convert to per rad/s.
    let scale = ts / (2.0 * std::f64::consts::PI * wpow * count as f64);
    let power = acc
        .iter()
        .enumerate()
        .map(|(k, a)| a * scale * if k == 0 || k == half { 1.0 } else { 2.0 })
        .collect();
    let omega = (0..=half)
        .map(|k| 2.0 * std::f64::consts::PI * k as f64 / (segment as f64 * ts))
        .collect();
    Ok(Periodogram { omega, power })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The bilinear Butterworth has the closed-form magnitude
        /// |H|^2 = 1 / (1 + (tan(w T/2) / tan(wc T/2))^(2n)).
        #[test]
        fn magnitude_matches_closed_form(order in 1usize..9, wc_frac in 0.02f64..0.95, w_frac in 0.0f64..0.999) {
            let ts = 0.02;
            let nyq = std::f64::consts::PI / ts;
            let f = Butterworth::design(order, wc_frac * nyq, ts).unwrap();
            let w = w_frac * nyq;
            let r = ((w * ts / 2.0).tan() / (wc_frac * nyq * ts / 2.0).tan()).powi(2 * order as i32);
            let want = 1.0 / (1.0 + r).sqrt();
            prop_assert!((f.gain(w) - want).abs() < 1e-9);
        }
    }

    #[test]
    fn design_rejects_bad_arguments() {
        assert!(Butterworth::design(0, 1.0, 0.02).is_err());
        assert!(Butterworth::design(2, 200.0, 0.02).is_err());
        assert!(Butterworth::design(2, f64::NAN, 0.02).is_err());
        assert!(Butterworth::design(2, 1.0, 0.0).is_err());
    }

    #[test]
    fn filtfilt_is_zero_phase_with_squared_gain() {
        let ts = 0.02;
        let f = Butterworth::design(4, 20.0, ts).unwrap();
        let w = 12.0;
        let n = 2000;
        let x: Vec<f64> = (0..n).map(|k| (w * k as f64 * ts).sin() + 0.7).collect();
        let y = f.filtfilt(&x);
        let g2 = f.gain(w).powi(2);
        // Away from the ends the output is the input sine scaled by |H|^2, no shift.
        for k in 300..n - 300 {
            let want = g2 * (w * k as f64 * ts).sin() + 0.7;
            assert!((y[k] - want).abs() < 1e-6, "k={k}: {} vs {}", y[k], want);
        }
        // A constant passes unchanged, including the ends.
        let c = f.filtfilt(&vec![3.0; 100]);
        assert!(c.iter().all(|v| (v - 3.0).abs() < 1e-9));
    }

    #[test]
    fn causal_filter_matches_frequency_response() {
        let ts = 0.01;
        let f = Butterworth::design(3, 30.0, ts).unwrap();
        let w = 25.0;
        let n = 4000;
        let x: Vec<f64> = (0..n).map(|k| (w * k as f64 * ts).cos()).collect();
        let y = f.filter(&x);
        let h = f.response(w);
        for k in 2000..n {
            let want = (h * Complex::from_polar(1.0, w * k as f64 * ts)).re;
            assert!((y[k] - want).abs() < 1e-6);
        }
    }

    #[test]
    fn periodogram_finds_a_sine_and_integrates_to_variance() {
        let ts = 0.02;
        let w0 = 11.0;
        let x: Vec<f64> = (0..8192)
            .map(|k| {
                2.0 * (w0 * k as f64 * ts).sin() + 0.3 * ((k * 7919 % 101) as f64 / 50.0 - 1.0)
            })
            .collect();
        let p = periodogram(&x, ts, 1024).unwrap();
        let dw = p.omega[1];
        assert!((p.peak().unwrap() - w0).abs() <= dw);
        let var = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64
            - (x.iter().sum::<f64>() / x.len() as f64).powi(2);
        let total: f64 = p.power.iter().sum::<f64>() * dw;
        assert!((total - var).abs() < 0.05 * var, "{total} vs {var}");
        assert!(periodogram(&x, ts, 1000).is_err());
        assert!(periodogram(&x[..100], ts, 1024).is_err());
    }
}
