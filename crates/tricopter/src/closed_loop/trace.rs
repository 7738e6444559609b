//! The closed loop's trace (one row per sample), its CSV text and the
//! step-response figures.

/// One row of the closed-loop trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceRow {
    /// Time (s).
    pub t: f64,
    /// Rate references (rad/s).
    pub reference: [f64; 3],
    /// Throttle (us).
    pub throttle: f64,
    /// True body rates (rad/s).
    pub rates: [f64; 3],
    /// Gyro sample (rad/s).
    pub measured: [f64; 3],
    /// Estimated outputs `C x_hat` (rad/s); the measurement for the PI.
    pub estimated: [f64; 3],
    /// Pulses sent `[pwm1, pwm2, pwm3, servo]` (us).
    pub pwm: [f64; 4],
    /// Whether any pulse was clipped.
    pub saturated: bool,
    /// The MPC's optimal cost `J` of this step (6.3a), `NaN` for laws without one.
    pub cost: f64,
}

/// A closed-loop run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// One row per sample.
    pub rows: Vec<TraceRow>,
    /// The pulses at hover (trim), for the effort measure.
    pub trim_pwm: [f64; 4],
}

/// The bound on the true body rates beyond which a run counts as diverged
/// (rad/s): three times the largest rate of the scenario (released rates and
/// references), and at least this many rad/s.
pub const DIVERGENCE_MIN_BOUND: f64 = 5.0;

/// How a closed loop diverged (see [`StepMetrics::diverged`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Divergence {
    /// The axis (0 = p, 1 = q, 2 = r).
    pub axis: usize,
    /// The time the rate first left the bound (s).
    pub t: f64,
    /// The rate there (rad/s; may be non-finite).
    pub rate: f64,
    /// The bound it left (rad/s).
    pub bound: f64,
}

impl Divergence {
    /// The axis name `p`, `q` or `r`.
    pub fn axis_name(&self) -> &'static str {
        ["p", "q", "r"][self.axis.min(2)]
    }
}

impl core::fmt::Display for Divergence {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "the rate {} reached {:.3} rad/s at t = {:.2} s, beyond the divergence bound {:.1} rad/s",
            self.axis_name(),
            self.rate,
            self.t,
            self.bound
        )
    }
}

/// Step-response figures per axis `[p, q, r]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMetrics {
    /// Rise time (s): from the step until the rate first crosses 90 % of
    /// the step from below; `NaN` when it never does (the 90 % level is not
    /// reached, or the rate was already beyond it at the step and never
    /// came back below it: it did not rise). `NaN` for an axis without a step.
    pub rise_time: [f64; 3],
    /// Overshoot beyond the new reference, percent of the step.
    pub overshoot: [f64; 3],
    /// RMS tracking error `r - y` over the step window (rad/s).
    pub rms_error: [f64; 3],
    /// RMS pulse deviation from the trim over the whole run, per channel
    /// `[pwm1, pwm2, pwm3, servo]` (us).
    pub effort: [f64; 4],
    /// Largest pulse excursion beyond its range (us); 0 when always inside.
    pub max_bound_violation: f64,
    /// `Some` when the loop diverged (lost control): a true rate became
    /// non-finite or left
    /// `max(3 x the largest released rate or reference,`
    /// [`DIVERGENCE_MIN_BOUND`]`)`. The other figures of a diverged run
    /// mean nothing.
    pub diverged: Option<Divergence>,
}

impl Trace {
    /// The CSV text: `t, r_p, r_q, r_r, throttle, p, q, r, p_meas, q_meas,
    /// r_meas, p_est, q_est, r_est, pwm1, pwm2, pwm3, servo, saturated, J`.
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "t,r_p,r_q,r_r,throttle,p,q,r,p_meas,q_meas,r_meas,p_est,q_est,r_est,pwm1,pwm2,pwm3,servo,saturated,J\n",
        );
        for row in &self.rows {
            let mut v: Vec<String> = vec![format!("{:.4}", row.t)];
            v.extend(row.reference.iter().map(|x| format!("{x}")));
            v.push(format!("{}", row.throttle));
            for arr in [&row.rates, &row.measured, &row.estimated] {
                v.extend(arr.iter().map(|x| format!("{x:.6e}")));
            }
            v.extend(row.pwm.iter().map(|x| format!("{x:.4}")));
            v.push(u8::from(row.saturated).to_string());
            v.push(if row.cost.is_finite() {
                format!("{:.6e}", row.cost)
            } else {
                String::new()
            });
            s.push_str(&v.join(","));
            s.push('\n');
        }
        s
    }

    /// The step-response figures for a step at `step_time` from `from` to `to`.
    pub fn step_metrics(&self, step_time: f64, from: [f64; 3], to: [f64; 3]) -> StepMetrics {
        let after: Vec<&TraceRow> = self
            .rows
            .iter()
            .filter(|r| r.t >= step_time - 1e-9)
            .collect();
        let mut m = StepMetrics {
            rise_time: [f64::NAN; 3],
            overshoot: [0.0; 3],
            rms_error: [0.0; 3],
            effort: [0.0; 4],
            max_bound_violation: 0.0,
            diverged: self.divergence(from, to),
        };
        for k in 0..3 {
            let d = to[k] - from[k];
            if d.abs() > 1e-12 {
                let frac = |r: &TraceRow| (r.rates[k] - from[k]) / d;
                // The first crossing of 90 % from below, after the step.
                let below = after.iter().position(|r| frac(r) < 0.9);
                let t90 =
                    below.and_then(|i| after[i..].iter().find(|r| frac(r) >= 0.9).map(|r| r.t));
                if let Some(b) = t90 {
                    m.rise_time[k] = b - step_time;
                }
                let peak = after.iter().map(|r| frac(r)).fold(f64::MIN, f64::max);
                m.overshoot[k] = ((peak - 1.0) * 100.0).max(0.0);
            }
            let n = after.len().max(1) as f64;
            m.rms_error[k] = (after
                .iter()
                .map(|r| (r.reference[k] - r.rates[k]).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
        }
        let n = self.rows.len().max(1) as f64;
        for i in 0..4 {
            m.effort[i] = (self
                .rows
                .iter()
                .map(|r| (r.pwm[i] - self.trim_pwm[i]).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
        }
        let ranges = [
            kestrel_tricopter_model::ESC_PWM_RANGE,
            kestrel_tricopter_model::ESC_PWM_RANGE,
            kestrel_tricopter_model::ESC_PWM_RANGE,
            kestrel_tricopter_model::SERVO_PWM_RANGE,
        ];
        for r in &self.rows {
            for (i, &(lo, hi)) in ranges.iter().enumerate() {
                m.max_bound_violation = m.max_bound_violation.max(lo - r.pwm[i]).max(r.pwm[i] - hi);
            }
        }
        m
    }

    /// The first row whose true rate is non-finite or beyond the
    /// divergence bound of [`StepMetrics::diverged`].
    fn divergence(&self, from: [f64; 3], to: [f64; 3]) -> Option<Divergence> {
        let first = self.rows.first()?;
        let scale = first
            .rates
            .iter()
            .chain(&from)
            .chain(&to)
            .fold(0.0_f64, |a, v| a.max(v.abs()));
        let bound = (3.0 * scale).max(DIVERGENCE_MIN_BOUND);
        self.rows.iter().find_map(|r| {
            (0..3)
                .find(|&k| !r.rates[k].is_finite() || r.rates[k].abs() > bound)
                .map(|axis| Divergence {
                    axis,
                    t: r.t,
                    rate: r.rates[axis],
                    bound,
                })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t: f64, rates: [f64; 3]) -> TraceRow {
        TraceRow {
            t,
            reference: [1.0, 1.0, 1.0],
            throttle: 1500.0,
            rates,
            measured: rates,
            estimated: rates,
            pwm: [1500.0, 1500.0, 1500.0, 0.0],
            saturated: false,
            cost: f64::NAN,
        }
    }

    /// p rises from 0 to 1 at t = 0.06 s after the step at 0; q sits at
    /// 1.2 (beyond the reference) throughout, never rising; r stays at 0.5.
    fn trace() -> Trace {
        let p = [0.0, 0.05, 0.5, 0.95, 1.0, 1.0];
        Trace {
            rows: (0..6)
                .map(|i| row(0.02 * i as f64, [p[i], 1.2, 0.5]))
                .collect(),
            trim_pwm: [1500.0, 1500.0, 1500.0, 0.0],
        }
    }

    #[test]
    fn rise_time_is_measured_from_the_step_and_nan_when_never_risen() {
        let m = trace().step_metrics(0.0, [0.0; 3], [1.0; 3]);
        assert!((m.rise_time[0] - 0.06).abs() < 1e-12, "{m:?}");
        // Already beyond 90 % at the step and never below it: no rise
        // (the old 10-90 % figure was 0 s, the best of any axis).
        assert!(m.rise_time[1].is_nan(), "{m:?}");
        // 90 % never reached.
        assert!(m.rise_time[2].is_nan(), "{m:?}");
        assert_eq!(m.diverged, None);
    }

    #[test]
    fn a_run_beyond_the_bound_or_non_finite_is_diverged() {
        let mut t = trace();
        t.rows[4].rates[1] = 25.0;
        let d = t.step_metrics(0.0, [0.0; 3], [1.0; 3]).diverged.unwrap();
        assert_eq!((d.axis, d.rate, d.bound), (1, 25.0, 5.0));
        assert!(d.to_string().contains("rate q reached 25"), "{d}");
        let mut t = trace();
        t.rows[5].rates[2] = f64::NAN;
        let d = t.step_metrics(0.0, [0.0; 3], [1.0; 3]).diverged.unwrap();
        assert_eq!(d.axis, 2);
    }
}
