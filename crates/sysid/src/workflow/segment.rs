//! Time intervals of one experiment or of all, and the data they select.

use crate::data::{IoData, TimeInterval};
use crate::error::{Result, SysidError};

/// A time interval, optionally restricted to one experiment (flight) of
/// the data: `"2@181.66:219.60"` is the interval in the second experiment
/// (1-based, in the order the experiments were loaded or merged), a plain
/// `"181.66:219.60"` takes the interval from every experiment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// The experiment (0-based index); `None`: every experiment.
    pub experiment: Option<usize>,
    /// The interval in the units of the time column.
    pub interval: TimeInterval,
}

impl Segment {
    /// An interval taken from every experiment.
    pub fn all(interval: TimeInterval) -> Self {
        Segment {
            experiment: None,
            interval,
        }
    }

    /// Parses a comma-separated list of `[N@]start:end` (N 1-based).
    pub fn parse_list(text: &str) -> Result<Vec<Segment>> {
        text.split(',')
            .filter(|s| !s.trim().is_empty())
            .map(|part| {
                let (exp, iv) = match part.split_once('@') {
                    Some((n, iv)) => {
                        let n: usize = n.trim().parse().map_err(|_| {
                            SysidError::invalid(format!(
                                "segment \"{part}\": \"{n}\" is not an experiment number (1, 2, ...)"
                            ))
                        })?;
                        if n == 0 {
                            return Err(SysidError::invalid(format!(
                                "segment \"{part}\": experiments are numbered from 1"
                            )));
                        }
                        (Some(n - 1), iv)
                    }
                    None => (None, part),
                };
                let ivs = TimeInterval::parse_list(iv)?;
                match ivs.as_slice() {
                    [one] => Ok(Segment {
                        experiment: exp,
                        interval: *one,
                    }),
                    _ => Err(SysidError::invalid(format!(
                        "segment \"{part}\" is not [N@]start:end"
                    ))),
                }
            })
            .collect()
    }
}

/// The first and last sample time of the data a segment draws on (its
/// experiment's, or the earliest and latest of all experiments').
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleSpan {
    /// Time of the first sample.
    pub first: f64,
    /// Time of the last sample.
    pub last: f64,
}

impl Segment {
    /// The samples' span when the segment's interval reaches beyond it by
    /// more than half a sample period at either end (selection then takes
    /// only the part that has samples, which a caller may want to say or
    /// refuse); `None` when the interval lies within, or when the
    /// experiment does not exist (which [`select_segments`] reports).
    ///
    /// ```
    /// use kestrel_sysid::IoData;
    /// use kestrel_sysid::workflow::{SampleSpan, Segment};
    /// use nalgebra::DMatrix;
    /// // Samples at 0, 0.5, ..., 4.5 s.
    /// let data = IoData::new(0.5, DMatrix::zeros(10, 1), DMatrix::zeros(10, 1)).unwrap();
    /// let within = Segment::parse_list("1:4.7").unwrap()[0];
    /// assert_eq!(within.beyond_samples(&data), None);
    /// let beyond = Segment::parse_list("1:5").unwrap()[0];
    /// assert_eq!(beyond.beyond_samples(&data), Some(SampleSpan { first: 0.0, last: 4.5 }));
    /// ```
    pub fn beyond_samples(&self, data: &IoData) -> Option<SampleSpan> {
        let experiments = data.experiments();
        let chosen = match self.experiment {
            Some(i) => experiments.get(i..=i)?,
            None => experiments,
        };
        let first = chosen
            .iter()
            .filter_map(|e| e.t.first().copied())
            .reduce(f64::min)?;
        let last = chosen
            .iter()
            .filter_map(|e| e.t.last().copied())
            .reduce(f64::max)?;
        let slack = 0.5 * data.ts();
        (self.interval.start < first - slack || self.interval.end > last + slack)
            .then_some(SampleSpan { first, last })
    }
}

/// The samples of `data` in the segments, every piece its own experiment.
pub fn select_segments(data: &IoData, segments: &[Segment]) -> Result<IoData> {
    let mut parts = Vec::with_capacity(segments.len());
    for s in segments {
        let part = match s.experiment {
            None => data.select(&[s.interval])?,
            Some(i) => {
                let e = data.experiments().get(i).ok_or_else(|| {
                    SysidError::invalid(format!(
                        "segment {}@{}:{}: the data have {} experiment(s)",
                        i + 1,
                        s.interval.start,
                        s.interval.end,
                        data.experiments().len()
                    ))
                })?;
                IoData::from_experiments(
                    data.ts(),
                    data.input_names().to_vec(),
                    data.output_names().to_vec(),
                    vec![e.clone()],
                )?
                .select(&[s.interval])?
            }
        };
        parts.push(part);
    }
    IoData::merge(&parts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Experiment;
    use nalgebra::DMatrix;

    /// Two experiments at 0.5 s: 0..4.5 s and 10..12 s.
    fn two() -> IoData {
        let e = |t: Vec<f64>| Experiment {
            u: DMatrix::zeros(t.len(), 1),
            y: DMatrix::zeros(t.len(), 1),
            t,
        };
        IoData::from_experiments(
            0.5,
            vec!["u".into()],
            vec!["y".into()],
            vec![
                e((0..10).map(|k| 0.5 * f64::from(k)).collect()),
                e((20..25).map(|k| 0.5 * f64::from(k)).collect()),
            ],
        )
        .unwrap()
    }

    fn seg(text: &str) -> Segment {
        Segment::parse_list(text).unwrap()[0]
    }

    #[test]
    fn an_interval_beyond_its_experiments_samples_is_reported_with_their_span() {
        let data = two();
        let first = SampleSpan {
            first: 0.0,
            last: 4.5,
        };
        let second = SampleSpan {
            first: 10.0,
            last: 12.0,
        };
        // Within half a sample period at both ends.
        assert_eq!(seg("1@-0.2:4.7").beyond_samples(&data), None);
        assert_eq!(seg("2@9.8:12.2").beyond_samples(&data), None);
        // Beyond at the end, at the start.
        assert_eq!(seg("1@1:4.8").beyond_samples(&data), Some(first));
        assert_eq!(seg("1@-0.3:2").beyond_samples(&data), Some(first));
        assert_eq!(seg("2@9.7:11").beyond_samples(&data), Some(second));
        // Selection takes the part with samples only.
        let part = select_segments(&data, &[seg("1@1:100")]).unwrap();
        assert_eq!(part.experiments()[0].t.last(), Some(&4.5));
        // Every experiment: the span is the earliest to the latest sample,
        // so the gap between them is within.
        assert_eq!(seg("0:12").beyond_samples(&data), None);
        assert_eq!(
            seg("0:13").beyond_samples(&data),
            Some(SampleSpan {
                first: 0.0,
                last: 12.0
            })
        );
        // A missing experiment is select_segments' error, not a span.
        assert_eq!(seg("3@0:1").beyond_samples(&data), None);
        assert!(select_segments(&data, &[seg("3@0:1")]).is_err());
    }
}
