//! Fault injection for the HIL test (feature `hil-faults`, never in a
//! flight build): the host sends a `Bench`-kind frame (otherwise a
//! firmware-to-host kind) carrying a fault request, 5 bytes: an op code
//! and a little-endian `u32` argument.
//!
//! - [`HANG`]: the main loop stops (spins with interrupts on and without
//!   resetting the watchdog), as a firmware stuck in a loop would: the
//!   watchdog resets the MCU.
//! - [`STALL`]: the next period's solver runs slower, as a CPU stolen by
//!   interrupts or a slower clock would make it: in the fast-gradient
//!   builds each of its iterations takes `arg` cycles more ([`Slowed`],
//!   through the solver's deadline hook, so its cycle budget sees the
//!   overrun and stops the iterations); in the explicit-MPC builds (no
//!   iterations: a tree walk bounded by its depth) and the active-set QP
//!   builds (iterations bounded by the solver's cap) the law's call takes
//!   `arg` cycles more ([`Stall`]).

#[cfg(feature = "no-fgm")]
use kestrel_avr_rt::control::LawInfo;
use kestrel_avr_rt::cycles::CycleClock;
#[cfg(not(feature = "no-fgm"))]
use kestrel_avr_rt::cycles::Deadline;
use kestrel_avr_rt::cycles::timer1::Timer1Clock;
#[cfg(feature = "no-fgm")]
use kestrel_core::{ControlLaw, Error};

/// Op code: hang the main loop (the watchdog resets the MCU).
pub const HANG: u8 = 1;
/// Op code: the next solve takes `arg` more cycles per iteration (fast
/// gradient) or in all (explicit MPC).
pub const STALL: u8 = 2;

/// Busy-waits `cycles` cycles on `clock`.
fn spin(clock: &Timer1Clock, cycles: u32) {
    let t0 = clock.now();
    while clock.now().wrapping_sub(t0) < cycles {}
}

/// A deadline whose every check first takes `extra` cycles: each
/// iteration of the solver asking it runs `extra` cycles longer.
#[cfg(not(feature = "no-fgm"))]
pub struct Slowed<D> {
    /// The deadline.
    pub inner: D,
    /// Extra cycles per iteration.
    pub extra: u32,
    clock: Timer1Clock,
}

#[cfg(not(feature = "no-fgm"))]
impl<D> Slowed<D> {
    /// Wraps `inner`, timing the extra work with `clock`.
    pub fn new(inner: D, clock: Timer1Clock) -> Self {
        Slowed {
            inner,
            extra: 0,
            clock,
        }
    }
}

#[cfg(not(feature = "no-fgm"))]
impl<C: CycleClock, const STRIDE: u16> Slowed<kestrel_avr_rt::cycles::CycleBudget<C, STRIDE>> {
    /// Starts the budget at `start` ([`CycleBudget::restart_at`]).
    ///
    /// [`CycleBudget::restart_at`]: kestrel_avr_rt::cycles::CycleBudget::restart_at
    pub fn restart_at(&mut self, start: u32) {
        self.inner.restart_at(start);
    }
}

#[cfg(not(feature = "no-fgm"))]
impl<D: Deadline> Deadline for Slowed<D> {
    // Asked before every STRIDE-th iteration: the extra cycles of the
    // STRIDE iterations up to the next question.
    const STRIDE: u16 = D::STRIDE;
    fn expired(&mut self) -> bool {
        spin(&self.clock, self.extra.saturating_mul(u32::from(D::STRIDE)));
        self.inner.expired()
    }
}

/// A law that takes `extra` more cycles in its next call.
#[cfg(feature = "no-fgm")]
pub struct Stall<L> {
    /// The law.
    pub inner: L,
    /// Extra cycles of the next call.
    pub extra: u32,
    clock: Timer1Clock,
}

#[cfg(feature = "no-fgm")]
impl<L> Stall<L> {
    /// Wraps `inner`, timing the extra work with `clock`.
    pub fn new(inner: L, clock: Timer1Clock) -> Self {
        Stall {
            inner,
            extra: 0,
            clock,
        }
    }
}

#[cfg(feature = "no-fgm")]
impl<L: ControlLaw> ControlLaw for Stall<L> {
    type Scalar = L::Scalar;
    fn nx(&self) -> usize {
        self.inner.nx()
    }
    fn nr(&self) -> usize {
        self.inner.nr()
    }
    fn nu(&self) -> usize {
        self.inner.nu()
    }
    fn control(
        &mut self,
        x: &[L::Scalar],
        r: &[L::Scalar],
        u: &mut [L::Scalar],
    ) -> Result<(), Error> {
        let res = self.inner.control(x, r, u);
        spin(&self.clock, self.extra);
        res
    }
}

#[cfg(feature = "no-fgm")]
impl<L: LawInfo> LawInfo for Stall<L> {
    fn iterations(&self) -> u16 {
        self.inner.iterations()
    }
    fn restart(&mut self) {
        self.inner.restart()
    }
}

/// Carries out a fault request's payload; returns the extra solver cycles
/// requested for the next period (0 for none).
pub fn request(payload: &[u8]) -> u32 {
    let arg = match payload.get(1..5) {
        Some(b) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        None => 0,
    };
    match payload.first() {
        Some(&HANG) => loop {
            core::hint::spin_loop();
        },
        Some(&STALL) => arg,
        _ => 0,
    }
}
