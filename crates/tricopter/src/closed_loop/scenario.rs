//! The closed loop's scenario: initial rates, reference steps, throttle.

/// A reference change at a given time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceStep {
    /// Time of the change (s).
    pub time: f64,
    /// New rate references `[p, q, r]` (rad/s).
    pub rates: [f64; 3],
}

/// A closed-loop scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Length of the run (s).
    pub duration: f64,
    /// Body rates at `t = 0` (rad/s), in the air at the hover trim otherwise.
    pub initial_rates: [f64; 3],
    /// Rate references from `t = 0` until the first step.
    pub initial_reference: [f64; 3],
    /// Reference changes, in time order.
    pub steps: Vec<ReferenceStep>,
    /// Common throttle (us); `None` holds the hover throttle.
    pub throttle: Option<f64>,
}

impl Scenario {
    /// Section 7.7.1: released at rates `[2, 2, 2]` rad/s with zero
    /// reference; once settled (2 s) a step to `[1, -1, 0.5]` rad/s, held for 2 s.
    pub fn thesis_step() -> Self {
        Scenario {
            duration: 4.0,
            initial_rates: [2.0, 2.0, 2.0],
            initial_reference: [0.0; 3],
            steps: vec![ReferenceStep {
                time: 2.0,
                rates: [1.0, -1.0, 0.5],
            }],
            throttle: None,
        }
    }
    /// The rate references at time `t`.
    pub fn reference_at(&self, t: f64) -> [f64; 3] {
        self.steps
            .iter()
            .rev()
            .find(|s| t + 1e-9 >= s.time)
            .map_or(self.initial_reference, |s| s.rates)
    }
}

impl Scenario {
    /// The first reference step as `(time, from, to)`; without steps, a
    /// "step" at `t = 0` from and to the initial reference.
    pub fn first_step(&self) -> (f64, [f64; 3], [f64; 3]) {
        match self.steps.first() {
            Some(s) => (s.time, self.initial_reference, s.rates),
            None => (0.0, self.initial_reference, self.initial_reference),
        }
    }
}
