//! Fault injection for the HIL test (feature `hil-faults`, never in a
//! flight build): the host sends a `Bench`-kind frame (otherwise a
//! firmware-to-host kind) carrying a fault request, 5 bytes: an op code
//! and a little-endian `u32` argument.
//!
//! - [`HANG`]: the main loop stops (spins with interrupts on and without
//!   resetting the watchdog), as a firmware stuck in a loop would: the
//!   watchdog resets the MCU.
//! - [`STALL`]: the next period's law runs `arg` cycles longer, as a
//!   solver overrunning its time budget would ([`Stall`]).

use kestrel_avr_rt::control::LawInfo;
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::cycles::timer1::Timer1Clock;
use kestrel_core::{ControlLaw, Error};

/// Op code: hang the main loop (the watchdog resets the MCU).
pub const HANG: u8 = 1;
/// Op code: the next solve takes `arg` more cycles.
pub const STALL: u8 = 2;

/// A law that takes `extra` more cycles in its next call (then 0 again).
pub struct Stall<L> {
    /// The law.
    pub inner: L,
    /// Extra cycles of the next call.
    pub extra: u32,
    clock: Timer1Clock,
}

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
        let t0 = self.clock.now();
        while self.clock.now().wrapping_sub(t0) < self.extra {}
        self.extra = 0;
        res
    }
}

impl<L: LawInfo> LawInfo for Stall<L> {
    fn iterations(&self) -> u16 {
        self.inner.iterations()
    }
    fn restart(&mut self) {
        self.inner.restart()
    }
}

/// Carries out a fault request's payload; returns the extra solver cycles
/// requested (0 for none).
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
