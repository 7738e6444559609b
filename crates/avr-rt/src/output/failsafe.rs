//! [`Failsafe`]: the per-period decision (run, hold, safe output) from the
//! arrival of valid frames and non-finite values.

/// What the loop does this period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    /// Run the controller; `recovered` is true on the first period after a failsafe.
    Run {
        /// Restart estimator and integrators before running.
        recovered: bool,
    },
    /// Hold the previous outputs (one missing frame).
    Hold,
    /// Output the safe pulses.
    Safe,
}

/// Why the failsafe is active.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FailsafeReason {
    /// No valid frame for [`Failsafe::TIMEOUT_PERIODS`] periods.
    Timeout,
    /// A non-finite value in the command or the controller output.
    NonFinite,
    /// The gyro reads stuck or at full scale (`control::GyroCheck`).
    Sensor,
}

/// The failsafe state machine (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Failsafe {
    missed: u8,
    active: Option<FailsafeReason>,
    started: bool,
    /// How many times the failsafe was entered.
    pub entries: u16,
}

impl Default for Failsafe {
    fn default() -> Self {
        Self::new()
    }
}

impl Failsafe {
    /// Periods without a valid frame after which the safe output is held.
    pub const TIMEOUT_PERIODS: u8 = 2;

    /// A failsafe that is active until the first valid command arrives.
    pub const fn new() -> Self {
        Failsafe {
            missed: 0,
            active: Some(FailsafeReason::Timeout),
            started: false,
            entries: 0,
        }
    }

    /// The reason the failsafe is active, if it is.
    pub fn active(&self) -> Option<FailsafeReason> {
        self.active
    }

    fn enter(&mut self, why: FailsafeReason) {
        if self.active.is_none() {
            self.entries = self.entries.wrapping_add(1);
        }
        self.active = Some(why);
    }

    /// Decides this period's action. `fresh` is `Some(finite)` if a new valid
    /// frame arrived since the last tick (`finite` tells whether all its values are finite).
    pub fn on_tick(&mut self, fresh: Option<bool>) -> Decision {
        match fresh {
            Some(true) => {
                self.missed = 0;
                let recovered = self.active.is_some() && self.started;
                self.started = true;
                self.active = None;
                Decision::Run { recovered }
            }
            Some(false) => {
                self.missed = 0;
                self.enter(FailsafeReason::NonFinite);
                Decision::Safe
            }
            None => {
                self.missed = self.missed.saturating_add(1);
                if self.missed >= Self::TIMEOUT_PERIODS {
                    self.enter(FailsafeReason::Timeout);
                }
                if self.active.is_some() {
                    Decision::Safe
                } else {
                    Decision::Hold
                }
            }
        }
    }

    /// A fresh, finite frame whose gyro reading the loop's sensor check
    /// refused (stuck or at full scale): the failsafe becomes active at
    /// once and stays until a frame passes the check (then recovery, as
    /// after any failsafe).
    pub fn sensor_fault(&mut self) -> Decision {
        self.missed = 0;
        self.enter(FailsafeReason::Sensor);
        Decision::Safe
    }

    /// Reports a non-finite controller output in a period that ran: the
    /// failsafe becomes active at once.
    pub fn non_finite_output(&mut self) {
        self.enter(FailsafeReason::NonFinite);
    }
}
