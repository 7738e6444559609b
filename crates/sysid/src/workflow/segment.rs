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
