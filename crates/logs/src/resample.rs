//! Resampling onto a uniform grid by cell means (a box anti-aliasing
//! filter followed by decimation), never by picking samples.

/// A uniform grid: cell `k` covers `[start + k / rate_hz, start + (k + 1) / rate_hz)`
/// and is stamped with its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Start of the first cell, seconds.
    pub start: f64,
    /// Cells per second.
    pub rate_hz: f64,
    /// Number of cells.
    pub len: usize,
}

impl Grid {
    /// The whole cells that fit in `[start, end]`.
    pub fn covering(start: f64, end: f64, rate_hz: f64) -> Grid {
        let n = ((end - start) * rate_hz + 1e-9).floor();
        Grid {
            start,
            rate_hz,
            len: if n.is_finite() && n > 0.0 {
                n as usize
            } else {
                0
            },
        }
    }

    /// The cell centres.
    pub fn times(&self) -> Vec<f64> {
        (0..self.len)
            .map(|k| self.start + (k as f64 + 0.5) / self.rate_hz)
            .collect()
    }
}

/// One signal on a grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Resampled {
    /// The mean of the samples in each cell; a cell without samples
    /// interpolated linearly between its neighbours' means (held before
    /// the first and after the last); NaN everywhere when no cell has one.
    pub values: Vec<f64>,
    /// Cells that held no sample and were interpolated.
    pub filled: usize,
}

/// The cell means of the samples `(t, v)` (times non-decreasing, NaN
/// values ignored) on `grid`.
///
/// ```
/// use kestrel_logs::{Grid, resample};
/// // 1 kHz samples of a ramp, averaged into 100 Hz cells.
/// let t: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-3).collect();
/// let g = Grid::covering(0.0, 1.0, 100.0);
/// let r = resample(&t, &t, &g);
/// assert_eq!(r.values.len(), 100);
/// assert!((r.values[3] - 0.0345).abs() < 1e-12); // the mean of 0.030 ..= 0.039
/// ```
pub fn resample(t: &[f64], v: &[f64], grid: &Grid) -> Resampled {
    let mut sum = vec![0.0; grid.len];
    let mut count = vec![0usize; grid.len];
    let first = t.partition_point(|&x| x < grid.start);
    for (&x, &y) in t.iter().zip(v).skip(first) {
        let k = ((x - grid.start) * grid.rate_hz).floor();
        if !(k >= 0.0 && k < grid.len as f64) {
            if k >= grid.len as f64 {
                break;
            }
            continue;
        }
        if y.is_finite() {
            sum[k as usize] += y;
            count[k as usize] += 1;
        }
    }
    let mut values: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(&s, &c)| if c > 0 { s / c as f64 } else { f64::NAN })
        .collect();
    let filled = count.iter().filter(|&&c| c == 0).count();
    fill(&mut values);
    Resampled { values, filled }
}

/// Replaces NaN runs by linear interpolation between the neighbours
/// (held at the ends).
fn fill(v: &mut [f64]) {
    let known: Vec<usize> = (0..v.len()).filter(|&k| v[k].is_finite()).collect();
    let (Some(&a), Some(&b)) = (known.first(), known.last()) else {
        return;
    };
    let (va, vb) = (v[a], v[b]);
    v[..a].iter_mut().for_each(|x| *x = va);
    v[b + 1..].iter_mut().for_each(|x| *x = vb);
    for w in known.windows(2) {
        let (i, j) = (w[0], w[1]);
        for k in i + 1..j {
            let s = (k - i) as f64 / (j - i) as f64;
            v[k] = v[i] + s * (v[j] - v[i]);
        }
    }
}

/// The intervals in `[start, end]` longer than `max_gap` seconds without
/// a sample holding a number.
pub(crate) fn gaps(t: &[f64], v: &[f64], start: f64, end: f64, max_gap: f64) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    let mut last = start;
    for (&x, &y) in t.iter().zip(v) {
        if x < start || !y.is_finite() {
            continue;
        }
        if x > end {
            break;
        }
        if x - last > max_gap {
            out.push([last, x]);
        }
        last = x;
    }
    if end - last > max_gap {
        out.push([last, end]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn means_not_picks_and_gaps_filled() {
        // A 500 Hz square wave sampled at 1 kHz averages to its mean in
        // 100 Hz cells (sample picking would alias it to a constant 0 or 1).
        let t: Vec<f64> = (0..1000).map(|k| (k as f64 + 0.5) * 1e-3).collect();
        let v: Vec<f64> = (0..1000).map(|k| f64::from(u8::from(k % 2 == 0))).collect();
        let r = resample(&t, &v, &Grid::covering(0.0, 1.0, 100.0));
        assert!(r.values.iter().all(|&x| (x - 0.5).abs() < 1e-12));
        assert_eq!(r.filled, 0);
        // Samples at 0.05 and 0.25 only: cells in between interpolated.
        let r = resample(&[0.05, 0.25], &[1.0, 3.0], &Grid::covering(0.0, 0.3, 10.0));
        assert_eq!(r.values, [1.0, 2.0, 3.0]);
        assert_eq!(r.filled, 1);
        assert_eq!(
            gaps(&[0.0, 0.1, 0.5], &[1.0; 3], 0.0, 0.6, 0.2),
            [[0.1, 0.5]]
        );
    }
}
