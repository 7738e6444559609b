//! Cycle counting: Timer1 of the ATmega2560 runs at the CPU clock
//! (prescaler 1) and its overflow interrupt extends the 16-bit count to 32
//! bits (wrapping after 2^32 cycles, 268 s at 16 MHz; differences taken with
//! `wrapping_sub` stay correct across the wrap).

/// A source of a free-running 32-bit cycle count.
pub trait CycleClock {
    /// The current count.
    fn now(&self) -> u32;
}

/// A time limit an iterative solver checks between its iterations
/// (`fgm16::Fgm16Law::solve_until`): once it says so, the solver stops
/// with its current (feasible) iterate. `&mut self`: an implementation may
/// keep state, e.g. the length of the last iteration.
pub trait Deadline {
    /// `true` if [`Deadline::expired`] is always `false`: the solver then
    /// skips the check at compile time ([`NoDeadline`]).
    const NEVER: bool = false;
    /// The solver asks before every `STRIDE`-th iteration only (iterations
    /// 0, `STRIDE`, `2 STRIDE`, ...): each answer covers the `STRIDE`
    /// iterations up to the next question. At least 1.
    const STRIDE: u16 = 1;
    /// Whether the solver must stop now (before its next iteration, or
    /// its next `STRIDE` iterations).
    fn expired(&mut self) -> bool;
}

/// No limit: every iteration runs (compiles to nothing).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoDeadline;

impl Deadline for NoDeadline {
    const NEVER: bool = true;
    #[inline(always)]
    fn expired(&mut self) -> bool {
        false
    }
}

/// A cycle budget on a [`CycleClock`], asked every `STRIDE` iterations
/// ([`Deadline::STRIDE`]): expired when the next `STRIDE` iterations, if
/// they take as long as the last `STRIDE`, would end more than `budget`
/// cycles after the start. Start it at the beginning of each period
/// ([`CycleBudget::restart`], [`CycleBudget::restart_at`]); the first check
/// (no iteration measured yet) only compares the elapsed cycles with the
/// budget. A stride above 1 reads the clock less often (on the AVR each
/// check costs about 150 cycles, a fast-gradient iteration about 4,500)
/// and stops up to `STRIDE - 1` iterations earlier than needed.
///
/// ```
/// use core::cell::Cell;
/// use kestrel_avr_rt::cycles::{CycleBudget, CycleClock, Deadline};
/// struct Fake<'a>(&'a Cell<u32>);
/// impl CycleClock for Fake<'_> {
///     fn now(&self) -> u32 {
///         self.0.get()
///     }
/// }
/// let t = Cell::new(1000);
/// let mut b: CycleBudget<_> = CycleBudget::new(Fake(&t), 100); // asked every iteration
/// b.restart(); // period starts at 1000
/// t.set(1040);
/// assert!(!b.expired()); // 40 of 100 used
/// t.set(1070);
/// assert!(b.expired()); // 70 used, the last step took 30: 100 would be reached
/// ```
#[derive(Clone, Copy, Debug)]
pub struct CycleBudget<C, const STRIDE: u16 = 1> {
    clock: C,
    /// Cycles allowed from `start` to the end of the last iteration.
    pub budget: u32,
    start: u32,
    last: u32,
}

impl<C: CycleClock, const STRIDE: u16> CycleBudget<C, STRIDE> {
    /// A budget of `budget` cycles on `clock`, starting now.
    pub fn new(clock: C, budget: u32) -> Self {
        let now = clock.now();
        CycleBudget {
            clock,
            budget,
            start: now,
            last: now,
        }
    }
    /// Starts the budget now.
    pub fn restart(&mut self) {
        self.restart_at(self.clock.now());
    }
    /// Starts the budget at the count `start` (e.g. the period's tick).
    pub fn restart_at(&mut self, start: u32) {
        self.start = start;
        self.last = start;
    }
}

impl<C: CycleClock, const STRIDE: u16> Deadline for CycleBudget<C, STRIDE> {
    const STRIDE: u16 = if STRIDE == 0 { 1 } else { STRIDE };
    #[inline]
    fn expired(&mut self) -> bool {
        let now = self.clock.now();
        let step = now.wrapping_sub(self.last);
        self.last = now;
        let used = now.wrapping_sub(self.start);
        // The first check after a restart measures the set-up, not an
        // iteration: it predicts nothing (`step` is then the set-up's).
        let next = if step == used { 0 } else { step };
        used.saturating_add(next) >= self.budget
    }
}

/// Combines the software overflow count with a hardware counter reading.
///
/// `tov_pending` is the overflow flag read (with interrupts disabled) right
/// after the counter: if the counter has wrapped but its interrupt has not
/// run yet, a small counter value belongs to the next overflow period.
///
/// ```
/// use kestrel_avr_rt::cycles::extend;
/// assert_eq!(extend(3, 0x0005, true), 0x0004_0005); // wrapped, ISR pending
/// assert_eq!(extend(3, 0xFFF0, true), 0x0003_FFF0); // read before the wrap
/// assert_eq!(extend(3, 0x0005, false), 0x0003_0005);
/// ```
pub const fn extend(overflows: u16, tcnt: u16, tov_pending: bool) -> u32 {
    let hi = if tov_pending && tcnt < 0x8000 {
        overflows.wrapping_add(1)
    } else {
        overflows
    };
    ((hi as u32) << 16) | tcnt as u32
}

/// Running min / mean / max of a cycle count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleStats {
    /// Smallest sample (`u32::MAX` before the first).
    pub min: u32,
    /// Largest sample.
    pub max: u32,
    /// Sum of the samples.
    pub sum: u64,
    /// Number of samples.
    pub count: u32,
}

impl Default for CycleStats {
    fn default() -> Self {
        Self::new()
    }
}

impl CycleStats {
    /// No samples yet.
    pub const fn new() -> Self {
        CycleStats {
            min: u32::MAX,
            max: 0,
            sum: 0,
            count: 0,
        }
    }
    /// Adds a sample.
    pub fn add(&mut self, c: u32) {
        self.min = self.min.min(c);
        self.max = self.max.max(c);
        self.sum += c as u64;
        self.count += 1;
    }
    /// The mean, or `None` without samples.
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum as f64 / self.count as f64)
    }
}

/// Timer1 as the cycle counter (AVR only).
#[cfg(target_arch = "avr")]
pub mod timer1 {
    use super::{CycleClock, extend};
    use core::cell::UnsafeCell;
    use core::ptr::{read_volatile, write_volatile};

    const TCCR1A: *mut u8 = 0x80 as *mut u8;
    const TCCR1B: *mut u8 = 0x81 as *mut u8;
    const TCNT1L: *mut u8 = 0x84 as *mut u8;
    const TCNT1H: *mut u8 = 0x85 as *mut u8;
    const TIMSK1: *mut u8 = 0x6F as *mut u8;
    const TIFR1: *mut u8 = 0x36 as *mut u8;
    const SREG: *mut u8 = 0x5F as *mut u8;

    struct Overflows(UnsafeCell<u16>);
    // SAFETY: single core; written only by the overflow ISR, read with interrupts off.
    unsafe impl Sync for Overflows {}
    static OVERFLOWS: Overflows = Overflows(UnsafeCell::new(0));

    /// The Timer1 cycle clock. Create it with [`Timer1Clock::start`].
    #[derive(Clone, Copy, Debug)]
    pub struct Timer1Clock(());

    impl Timer1Clock {
        /// Configures Timer1 in normal mode at the CPU clock with the overflow
        /// interrupt enabled. The firmware must route `TIMER1_OVF`
        /// (`__vector_20`) to [`on_overflow`] and enable interrupts.
        ///
        /// # Safety
        /// Takes over Timer1; call once, before interrupts are enabled.
        pub unsafe fn start() -> Self {
            // SAFETY: the registers exist on the ATmega2560; the caller owns Timer1.
            unsafe {
                write_volatile(TCCR1A, 0);
                write_volatile(TCCR1B, 0);
                write_volatile(TCNT1H, 0);
                write_volatile(TCNT1L, 0);
                write_volatile(TIFR1, 1); // clear a stale overflow flag
                write_volatile(TIMSK1, 1); // TOIE1
                write_volatile(TCCR1B, 1); // CS10: clk/1
            }
            Timer1Clock(())
        }
    }

    impl CycleClock for Timer1Clock {
        #[inline]
        fn now(&self) -> u32 {
            // SAFETY: plain register reads with interrupts disabled around them.
            unsafe {
                let sreg = read_volatile(SREG);
                core::arch::asm!("cli", options(nostack, preserves_flags));
                let lo = read_volatile(TCNT1L); // low byte first latches the high byte
                let hi = read_volatile(TCNT1H);
                let pending = read_volatile(TIFR1) & 1 != 0;
                let ovf = read_volatile(OVERFLOWS.0.get());
                write_volatile(SREG, sreg);
                extend(ovf, u16::from_le_bytes([lo, hi]), pending)
            }
        }
    }

    /// The body of the Timer1 overflow interrupt.
    ///
    /// # Safety
    /// Call only from the `TIMER1_OVF` interrupt handler.
    #[inline(always)]
    pub unsafe fn on_overflow() {
        // SAFETY: interrupts are off inside the handler.
        unsafe {
            let p = OVERFLOWS.0.get();
            write_volatile(p, read_volatile(p).wrapping_add(1));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A simulated 16-bit timer with a lazily serviced overflow interrupt: the
    /// extended reading must equal the true count whatever the interrupt latency.
    #[test]
    fn extension_matches_true_count_under_isr_latency() {
        for latency in [0u32, 1, 5, 300] {
            let mut ovf_sw: u16 = 0;
            let mut pending_since: Option<u32> = None;
            let mut last = 0u32;
            for t in (0u32..400_000).step_by(37) {
                let tcnt = (t & 0xFFFF) as u16;
                // A wrap happened between the previous sample and this one?
                if t >> 16 != last >> 16 {
                    pending_since = Some(t);
                }
                // The ISR runs `latency` cycles after the wrap.
                if let Some(s) = pending_since
                    && t >= s + latency
                {
                    ovf_sw = ovf_sw.wrapping_add(1);
                    pending_since = None;
                }
                let got = extend(ovf_sw, tcnt, pending_since.is_some());
                assert_eq!(got, t, "latency {latency} at t = {t}");
                last = t;
            }
        }
    }

    #[test]
    fn stats() {
        let mut s = CycleStats::new();
        assert_eq!(s.mean(), None);
        for c in [10, 30, 20] {
            s.add(c);
        }
        assert_eq!((s.min, s.max, s.mean()), (10, 30, Some(20.0)));
    }
}
