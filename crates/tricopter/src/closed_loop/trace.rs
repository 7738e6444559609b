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

/// Step-response figures per axis `[p, q, r]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMetrics {
    /// 10 %-90 % rise time after the step (s); `NaN` if never reached.
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
        };
        for k in 0..3 {
            let d = to[k] - from[k];
            if d.abs() > 1e-12 {
                let frac = |r: &TraceRow| (r.rates[k] - from[k]) / d;
                let t10 = after.iter().find(|r| frac(r) >= 0.1).map(|r| r.t);
                let t90 = after.iter().find(|r| frac(r) >= 0.9).map(|r| r.t);
                if let (Some(a), Some(b)) = (t10, t90) {
                    m.rise_time[k] = b - a;
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
}
