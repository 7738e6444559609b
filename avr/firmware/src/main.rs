//! kestrel example firmware for the ATmega2560 (see README.md).
//!
//! Peripherals (16 MHz):
//! - Timer1: free-running cycle counter (prescaler 1, overflow interrupt);
//! - Timer4: fast PWM mode 14, 0.5 us ticks, TOP 39999 (50 Hz): servo on
//!   OC4A (PH3); its overflow flag paces the 50 Hz loop; its compare B
//!   interrupt, 15 ms into each period, is the output watchdog (safe
//!   pulses once the main loop has not written the outputs through two
//!   whole periods);
//! - Timer5: fast PWM mode 14, 0.5 us ticks, TOP 4999 (400 Hz): ESC 1-3 on
//!   OC5A/OC5B/OC5C (PL3/PL4/PL5);
//! - USART0: 250000 baud 8N1 (UBRR 3, exact at 16 MHz), receive interrupt
//!   into a ring buffer, transmit by polling;
//! - the watchdog: off during the boot, then a 64 ms reset timeout
//!   restarted every period (a main loop stuck for three periods resets
//!   the MCU; after any reset the outputs are the safe pulses until a
//!   valid command arrives).
#![no_std]
#![no_main]
#![feature(abi_avr_interrupt, asm_experimental_arch)]

use core::cell::UnsafeCell;
use core::ptr::{read_volatile, write_volatile};
use kestrel_avr_rt::control::{GyroCheck, Mixer, RateLoop};
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::cycles::timer1::{self, Timer1Clock};
use kestrel_avr_rt::frame::{
    Boot, Command, Frame, FrameDecoder, Kind, MAX_FRAME, Reply, SeqTracker, status,
};
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::output::{PwmLimits, RtScalar, SafeOutput};
use kestrel_avr_rt::progmem::{FarTable, TableRead};
use kestrel_avr_rt::{crc16, far_table};
use kestrel_core::{Matrix, Scalar};

#[cfg(all(feature = "fixed", not(feature = "fixed-mac")))]
type S = kestrel_core::Q16;
#[cfg(feature = "fixed-mac")]
type S = kestrel_avr_rt::mac::Q16Mac;
#[cfg(not(any(feature = "fixed", feature = "fixed-mac")))]
type S = f32;

/// Boot-frame configuration code: bit 0 fixed point, bit 1 the MAC variant,
/// bit 2 explicit MPC, bit 3 its Ns = 2 table, bit 4 the active-set QP
/// (kestrel-qp, f32), bit 5 the fixed-point one (`kestrel_avr_rt::qp16`).
const CONFIG: u8 = (if cfg!(feature = "fixed-mac") {
    3
} else if cfg!(feature = "fixed") {
    1
} else {
    0
}) | if cfg!(feature = "empc") { 4 } else { 0 }
    | if cfg!(feature = "empc-ns2") { 8 } else { 0 }
    | if cfg!(feature = "qp") { 16 } else { 0 }
    | if cfg!(feature = "qp16") { 32 } else { 0 };

/// The explicit controller's 16-bit table (kestrel_avr_rt::explicit::tree16),
/// in flash, read with ELPM; the same bytes for every scalar.
#[cfg(all(feature = "empc", not(feature = "empc-ns2")))]
#[unsafe(link_section = ".text.kestrel_tables")]
#[used]
static EMPC_TABLE: [u8; generated_empc::EMPC16_BYTES] = generated_empc::EMPC16;

/// Generated controller values (host: `kestrel codegen`).
#[allow(dead_code)]
mod generated;
#[cfg(feature = "empc")]
#[allow(dead_code)]
mod generated_empc;
/// The Ns = 2 explicit MPC's table (wide layout, flash chunks).
#[cfg(feature = "empc-ns2")]
#[allow(dead_code)]
mod generated_empc_ns2;
/// The `qp` builds' box QP (kestrel-qp).
#[cfg(feature = "qp")]
#[allow(dead_code)]
mod generated_qp;
/// The `qp` builds' set-up.
#[cfg(feature = "qp")]
mod qp;
/// The exact MPC's on-target check.
#[cfg(any(feature = "qp-check", feature = "qp16-check"))]
mod qp_check;
/// The `qp` builds' law (also the HIL test's host reference, in f64).
#[cfg(feature = "qp")]
#[allow(dead_code)]
mod qp_law;
#[cfg(all(
    any(feature = "qp-check", feature = "qp16-check"),
    feature = "hil-faults"
))]
compile_error!("`hil-faults` wraps the law; `qp-check` needs the bare QP law");
#[cfg(all(
    feature = "qp",
    any(feature = "fixed", feature = "fixed-mac", feature = "empc")
))]
compile_error!("`qp` runs kestrel-qp in f32: not with `fixed`, `fixed-mac` or `empc`");
/// The `qp16` builds' fixed-point box QP.
#[cfg(feature = "qp16")]
#[allow(dead_code)]
mod generated_qp16;
/// The `qp16` builds' law.
#[cfg(feature = "qp16")]
mod qp16_law;
#[cfg(all(feature = "qp16", any(feature = "qp", feature = "empc")))]
compile_error!("`qp16` is a law of its own: not with `qp` or `empc`");
/// Fault injection for the HIL test.
#[cfg(feature = "hil-faults")]
mod faults;
#[cfg(all(feature = "hil-faults", feature = "empc-check"))]
compile_error!("`hil-faults` wraps the law; `empc-check` needs the bare explicit law");
/// Controller tables in flash (see tables.rs).
mod tables;
use tables::*;

/// Reads table entry `i` as the loop's scalar.
trait TableScalar: Sized {
    fn read(t: &FarTable, i: usize) -> Self;
}
impl TableScalar for f32 {
    fn read(t: &FarTable, i: usize) -> Self {
        t.read_f32(4 * i as u32).unwrap_or(f32::NAN)
    }
}
impl TableScalar for kestrel_core::Q16 {
    fn read(t: &FarTable, i: usize) -> Self {
        kestrel_core::Fixed(t.read_i32(4 * i as u32).unwrap_or(i32::MAX))
    }
}
impl TableScalar for kestrel_avr_rt::mac::Q16Mac {
    fn read(t: &FarTable, i: usize) -> Self {
        Self::from_bits(t.read_i32(4 * i as u32).unwrap_or(i32::MAX))
    }
}

#[cfg(feature = "far-selftest")]
#[unsafe(link_section = ".progmem.data.filler0")]
#[used]
static FILLER0: [u8; 32000] = [0x5A; 32000];
#[cfg(feature = "far-selftest")]
#[unsafe(link_section = ".progmem.data.filler1")]
#[used]
static FILLER1: [u8; 32000] = [0xA5; 32000];

// ---- registers (data-space addresses) ----
const SREG: *mut u8 = 0x5F as *mut u8;
const UCSR0A: *mut u8 = 0xC0 as *mut u8;
const UCSR0B: *mut u8 = 0xC1 as *mut u8;
const UCSR0C: *mut u8 = 0xC2 as *mut u8;
const UBRR0L: *mut u8 = 0xC4 as *mut u8;
const UBRR0H: *mut u8 = 0xC5 as *mut u8;
const UDR0: *mut u8 = 0xC6 as *mut u8;
const TCCR4A: *mut u8 = 0xA0 as *mut u8;
const TCCR4B: *mut u8 = 0xA1 as *mut u8;
const ICR4L: *mut u8 = 0xA6 as *mut u8;
const OCR4AL: *mut u8 = 0xA8 as *mut u8;
const OCR4BL: *mut u8 = 0xAA as *mut u8;
const TIMSK4: *mut u8 = 0x72 as *mut u8;
const TIFR4: *mut u8 = 0x39 as *mut u8;
const TCCR5A: *mut u8 = 0x120 as *mut u8;
const TCCR5B: *mut u8 = 0x121 as *mut u8;
const ICR5L: *mut u8 = 0x126 as *mut u8;
const OCR5AL: *mut u8 = 0x128 as *mut u8;
const OCR5BL: *mut u8 = 0x12A as *mut u8;
const OCR5CL: *mut u8 = 0x12C as *mut u8;
const DDRH: *mut u8 = 0x101 as *mut u8;
const DDRL: *mut u8 = 0x10A as *mut u8;
const MCUSR: *mut u8 = 0x54 as *mut u8;

/// Sets the watchdog control register (`WDE | prescaler` bits, or 0 for
/// off) with the timed sequence: `WDCE | WDE`, then the value within four
/// cycles, interrupts off. Clears the watchdog reset flag first (while it
/// is set the watchdog cannot be turned off: after a watchdog reset it
/// restarts at 16 ms, shorter than the boot).
fn watchdog(value: u8) {
    // SAFETY: MCUSR and WDTCSR exist on the ATmega2560; the asm block is
    // the datasheet's timed sequence and restores SREG.
    unsafe {
        write_volatile(MCUSR, read_volatile(MCUSR) & !(1 << 3)); // WDRF
        core::arch::asm!(
            "in {sreg}, 0x3f",
            "cli",
            "wdr",
            "sts 0x60, {enable}", // WDTCSR
            "sts 0x60, {value}",
            "out 0x3f, {sreg}",
            sreg = out(reg) _,
            enable = in(reg) 0x18u8, // WDCE | WDE
            value = in(reg) value,
        );
    }
}

/// Restarts the watchdog's timeout.
#[inline(always)]
fn watchdog_reset() {
    // SAFETY: `wdr` only restarts the watchdog timer.
    unsafe { core::arch::asm!("wdr", options(nomem, nostack, preserves_flags)) };
}

/// The fast gradient's cycle budget, from the period's tick to the end of
/// its last iteration: 240,000 cycles (15 ms of the 20 ms period). Its
/// iterations normally end about 150,000 cycles after the tick (Kalman
/// measurement update and set-up included; docs/avr-rt.md), so the budget
/// never cuts a normal solve; the 80,000 cycles (5 ms) left cover the rest
/// of the period with a margin of more than two: the time update, mixer
/// and outputs (a few thousand cycles) and the reply, 35 bytes sent by
/// polling at 250 kbaud (22,400 cycles). A solve slowed past it (CPU
/// stolen by interrupts, a slower clock) stops early with its current
/// iterate, in the box; the reply's `iterations` tells.
#[cfg(not(feature = "no-fgm"))]
const FGM_BUDGET: u32 = 240_000;

/// The budget is checked before every 4th iteration (7 clock reads in the
/// 27 iterations, about 1,000 cycles; before each iteration it cost about
/// 4,500 cycles, 3.6 % of the solve); each check asks whether the next 4
/// iterations fit.
#[cfg(not(feature = "no-fgm"))]
const FGM_STRIDE: u16 = 4;

/// WDTCSR value: reset mode (WDE), prescaler 2 (8k cycles of the 128 kHz
/// oscillator: 64 ms).
const WATCHDOG_64MS: u8 = 0x08 | 0x02;

/// Writes a 16-bit timer register: high byte first (through TEMP).
#[inline(always)]
unsafe fn write16(low: *mut u8, v: u16) {
    // SAFETY: `low` is the low byte of a 16-bit timer register pair.
    unsafe {
        write_volatile(low.add(1), (v >> 8) as u8);
        write_volatile(low, v as u8);
    }
}

// ---- receive ring buffer, filled by the USART0 receive interrupt ----
const RING: usize = 128;
struct Ring {
    buf: UnsafeCell<[u8; RING]>,
    head: UnsafeCell<u8>,
    tail: UnsafeCell<u8>,
}
// SAFETY: single core; the ISR writes buf/head, the main loop reads buf and
// writes tail; each index is a single byte (atomic on the AVR).
unsafe impl Sync for Ring {}
static RX: Ring = Ring {
    buf: UnsafeCell::new([0; RING]),
    head: UnsafeCell::new(0),
    tail: UnsafeCell::new(0),
};

fn rx_pop() -> Option<u8> {
    // SAFETY: see `Ring`.
    unsafe {
        let t = read_volatile(RX.tail.get());
        if t == read_volatile(RX.head.get()) {
            return None;
        }
        let b = read_volatile((RX.buf.get() as *const u8).add(t as usize));
        write_volatile(RX.tail.get(), ((t as usize + 1) % RING) as u8);
        Some(b)
    }
}

/// USART0 receive complete.
#[unsafe(no_mangle)]
pub unsafe extern "avr-interrupt" fn __vector_25() {
    // SAFETY: interrupt context, see `Ring`.
    unsafe {
        let b = read_volatile(UDR0);
        let h = read_volatile(RX.head.get());
        let next = ((h as usize + 1) % RING) as u8;
        if next != read_volatile(RX.tail.get()) {
            write_volatile((RX.buf.get() as *mut u8).add(h as usize), b);
            write_volatile(RX.head.get(), next);
        }
    }
}

/// Timer1 overflow: extends the cycle counter.
#[unsafe(no_mangle)]
pub unsafe extern "avr-interrupt" fn __vector_20() {
    // SAFETY: called only as the TIMER1_OVF handler.
    unsafe { timer1::on_overflow() }
}

// ---- output watchdog ----
/// Timer4 compare-B interrupts since the main loop last wrote the outputs.
struct Stale(UnsafeCell<u8>);
// SAFETY: single core; a single byte, written by the ISR and by the main
// loop with interrupts off.
unsafe impl Sync for Stale {}
static STALE: Stale = Stale(UnsafeCell::new(0));

/// Timer4 compare match B, 15 ms into every 20 ms period: the output
/// watchdog. The main loop writes the outputs about 10 ms into a period
/// (later after an overrun), which sets the count back to 0; this
/// interrupt counts up. At 3 the outputs were not written through the
/// last two whole periods (hung or stalled): the safe pulses are written
/// here (the ESCs take them within 2.5 ms, the servo at the next period),
/// as the failsafe does after two periods without a valid frame. The
/// watchdog timer then resets a hung MCU.
#[unsafe(no_mangle)]
pub unsafe extern "avr-interrupt" fn __vector_43() {
    // SAFETY: interrupt context (interrupts off), see `Stale`.
    unsafe {
        let n = read_volatile(STALE.0.get()).saturating_add(1);
        write_volatile(STALE.0.get(), n);
        if n >= 3 {
            write_pwm(&SafeOutput::default().pwm(&PwmLimits::default()));
        }
    }
}

fn tx(bytes: &[u8]) {
    for &b in bytes {
        // SAFETY: USART0 registers; wait for an empty data register.
        unsafe {
            while read_volatile(UCSR0A) & (1 << 5) == 0 {}
            write_volatile(UDR0, b);
        }
    }
}

fn send(kind: Kind, seq: u8, payload: &[u8]) {
    let mut buf = [0u8; MAX_FRAME];
    if let Some(f) = Frame::new(kind, seq, payload) {
        if let Ok(n) = f.encode(&mut buf) {
            tx(buf.get(..n).unwrap_or(&[]));
        }
    }
}

/// Writes the compare registers (interrupts must be off: the 16-bit
/// writes go through the timers' shared TEMP byte, which the output
/// watchdog's interrupt also uses).
///
/// # Safety
/// Call with interrupts disabled.
unsafe fn write_pwm(p: &[u16; 4]) {
    // SAFETY: Timer4/Timer5 compare registers; 2 ticks per microsecond.
    unsafe {
        write16(OCR5AL, p[0] * 2);
        write16(OCR5BL, p[1] * 2);
        write16(OCR5CL, p[2] * 2);
        write16(OCR4AL, p[3] * 2);
    }
}

/// Writes the outputs and tells the output watchdog.
fn set_pwm(p: &[u16; 4]) {
    // SAFETY: interrupts off around the register writes and the watchdog
    // byte (SREG restored after).
    unsafe {
        let sreg = read_volatile(SREG);
        core::arch::asm!("cli", options(nostack, preserves_flags));
        write_pwm(p);
        write_volatile(STALE.0.get(), 0);
        write_volatile(SREG, sreg);
    }
}

fn init_hw() {
    // SAFETY: one-time peripheral set-up before interrupts are enabled.
    unsafe {
        write_volatile(UBRR0H, 0);
        write_volatile(UBRR0L, 3); // 16 MHz / (16 * (3 + 1)) = 250000 baud
        write_volatile(UCSR0A, 0);
        write_volatile(UCSR0C, 0x06); // 8N1
        write_volatile(UCSR0B, (1 << 7) | (1 << 4) | (1 << 3)); // RXCIE, RXEN, TXEN
        // Timer5: ESCs, fast PWM mode 14, clk/8, TOP 4999 (400 Hz).
        write16(ICR5L, 4999);
        write_volatile(TCCR5A, 0xAA);
        write_volatile(TCCR5B, 0x1A);
        // Timer4: servo, fast PWM mode 14, clk/8, TOP 39999 (50 Hz).
        write16(ICR4L, 39999);
        write16(OCR4BL, 30000); // output watchdog, 15 ms into the period
        write_volatile(TCCR4A, 0x82);
        write_volatile(TCCR4B, 0x1A);
        write_volatile(DDRL, read_volatile(DDRL) | 0x38);
        write_volatile(DDRH, read_volatile(DDRH) | 0x08);
    }
}

fn v(t: &FarTable, i: usize) -> S {
    S::read(t, i)
}
fn va<const N: usize>(t: &FarTable, at: usize) -> [S; N] {
    core::array::from_fn(|i| v(t, at + i))
}
#[cfg_attr(feature = "no-fgm", allow(dead_code))]
fn vm<const R: usize, const C: usize>(t: &FarTable, at: usize) -> Matrix<S, R, C> {
    Matrix::from_fn(|i, j| v(t, at + C * i + j))
}

#[unsafe(no_mangle)]
pub extern "C" fn main() -> ! {
    // Off during the boot (self-tests, and the benchmark builds' long runs).
    watchdog(0);
    init_hw();
    // Keep the fillers (the linker drops unreferenced sections).
    #[cfg(feature = "far-selftest")]
    {
        core::hint::black_box(FILLER0.as_ptr());
        core::hint::black_box(FILLER1.as_ptr());
    }
    // SAFETY: Timer1 is ours; interrupts are still off.
    let clock = unsafe { Timer1Clock::start() };
    let table = far_table!(TABLE);
    let limits = PwmLimits::default();
    let safe = SafeOutput::default();
    set_pwm(&safe.pwm(&limits));

    // Table layout: see generated.rs. The Kalman filter runs with 16-bit
    // coefficients on the hardware multiplier (kestrel_avr_rt::kalman16).
    if KF16.check().is_err() {
        loop {}
    }
    let filter = Kalman16::<S, NX, 4, 3>::new(KF16);
    #[cfg(not(feature = "no-fgm"))]
    let law = {
        use kestrel_avr_rt::fgm16::Fgm16Law;
        use kestrel_fgm::FgmTables;
        let fgm = FgmTables::<S, NZ, NP, FGM_T> {
            m: vm(&table, FGM_M),
            k_theta: vm(&table, FGM_K),
            k0: va(&table, FGM_K0),
            lo_theta: vm(&table, FGM_LO),
            lo0: va(&table, FGM_LO0),
            hi_theta: vm(&table, FGM_HI),
            hi0: va(&table, FGM_HI0),
            d: va(&table, FGM_D),
            d_inv: va(&table, FGM_DINV),
            betas: va(&table, FGM_BETAS),
            iterations: FGM_ITERATIONS,
            warm_iterations: FGM_ITERATIONS,
            shift: 0,
        };
        // Set-up in S, iterations in Q15.16 with 16-bit M rows (kestrel_avr_rt::fgm16).
        let Ok(law) = Fgm16Law::<S, NZ, NP, FGM_T, 4>::new(
            fgm,
            FGM16_M,
            FGM16_BETAS,
            NX,
            FGM_WARM,
            FGM_LOOP_ITERATIONS as u16,
        ) else {
            loop {}
        };
        // The solve stops its iterations once the next FGM_STRIDE would end
        // past FGM_BUDGET cycles after the tick (restarted at every tick).
        let budget = kestrel_avr_rt::cycles::CycleBudget::<_, FGM_STRIDE>::new(clock, FGM_BUDGET);
        #[cfg(feature = "hil-faults")]
        let budget = faults::Slowed::new(budget, clock);
        kestrel_avr_rt::fgm16::Fgm16Deadline {
            law,
            deadline: budget,
        }
    };
    // Explicit MPC: kestrel-empc's tree with 16-bit rows, read from flash
    // through ELPM by an assembly MAC (kestrel_avr_rt::explicit::tree16).
    #[cfg(all(feature = "empc", not(feature = "empc-ns2")))]
    let law = {
        use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
        let Ok(tree) = Tree16::new(far_table!(EMPC_TABLE), generated_empc::EMPC16_LAYOUT) else {
            loop {}
        };
        let Ok(law) = Empc16Law::<S, _, NP, 4, { generated_empc::EMPC16_ROWS }>::new(tree, NX)
        else {
            loop {}
        };
        law
    };
    // Ns = 2: the wide 16-bit tree in flash chunks, walked in Rust with a
    // direct-mapped cache of 64 rows.
    #[cfg(feature = "empc-ns2")]
    let law = {
        use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
        let Some(chunks) = generated_empc_ns2::empc_ns2_table() else {
            loop {}
        };
        let Ok(tree) = Tree16::new(chunks, generated_empc_ns2::EMPC_NS2_LAYOUT) else {
            loop {}
        };
        let Ok(law) = Empc16Law::<S, _, NP, 4, 64>::new(tree, NX) else {
            loop {}
        };
        law
    };
    // The exact MPC: kestrel-qp's dual active-set solver in f32 on the box
    // QP of src/generated_qp.rs, its workspaces on main's frame (main
    // never returns).
    #[cfg(feature = "qp")]
    let mut qp_ws = qp::Workspace::new();
    #[cfg(feature = "qp")]
    let Some(law) = qp::law(&mut qp_ws, qp::SETTINGS, qp::WARM, NX) else {
        loop {}
    };
    // The exact MPC in fixed point (kestrel_avr_rt::qp16), tables in RAM.
    #[cfg(feature = "qp16")]
    let Ok(law) =
        qp16_law::Qp16Law::<S, NZ, NP, 4, _, _>::new(&generated_qp16::QP16, qp16_law::kernel(), NX)
    else {
        loop {}
    };
    let bias = va(&table, BIAS);
    let one = S::from_f32_fast(1.0);
    let mixer = Mixer::<S, 4> {
        m: Matrix::from_fn(|i, j| if i == j { one } else { S::ZERO }),
        offset: va(&table, MIX_OFFSET),
        throttle_gain: [one, one, one, S::ZERO],
    };
    #[cfg(all(feature = "hil-faults", feature = "no-fgm"))]
    let law = faults::Stall::new(law, clock);
    let Ok(mut rate_loop) = RateLoop::new(filter, law, bias, mixer, limits, safe) else {
        loop {}
    };
    // A stuck or railed gyro engages the failsafe (200 ms, 2000 deg/s).
    rate_loop.gyro_check = Some(GyroCheck::default());

    // SAFETY: enable interrupts now that the handlers' state is initialised.
    unsafe { core::arch::asm!("sei") };

    // Boot report: read the table back through ELPM and compare CRCs.
    let mut crc = 0xFFFFu16;
    for i in 0..table.len_bytes() {
        crc = kestrel_avr_rt::crc::crc16_update(crc, &[table.read_u8(i).unwrap_or(0)]);
    }
    let boot = Boot {
        table_address: table.address(),
        table_len: table.len_bytes() as u16,
        crc_read: crc,
        crc_expected: const { crc16(&TABLE) },
        config: CONFIG,
        // The MAC's assembly checked against core's Q16 on this very CPU.
        mac_mismatches: kestrel_avr_rt::mac::self_test(0x1234_5678, 16).min(255) as u8,
    };
    send(Kind::Boot, 0, &boot.to_payload());
    #[cfg(feature = "fgm-bench")]
    fgm_bench(&clock);
    #[cfg(feature = "empc-check")]
    empc_check(&mut rate_loop.law, &clock);
    #[cfg(feature = "qp-check")]
    {
        let mut ws = qp::Workspace::new();
        let cap1 = kestrel_qp::QpSettings {
            max_iterations: 1,
            ..qp::SETTINGS
        };
        if let Some(mut capped) = qp::law(&mut ws, cap1, false, NX) {
            use generated_qp::{QP_THETA_LB, QP_THETA_UB};
            let bx = (&QP_THETA_LB, &QP_THETA_UB);
            let mut out = |p: &[u8]| send(Kind::Bench, 0, p);
            let mut dec = FrameDecoder::new();
            let mut inp = |buf: &mut [u8; 40]| qp_check::recv_bench(&mut dec, rx_pop, buf);
            qp_check::check(
                &mut rate_loop.law,
                &mut capped,
                bx,
                NX,
                &clock,
                &mut out,
                &mut inp,
            );
        }
    }
    #[cfg(feature = "qp16-check")]
    {
        let cap1 = kestrel_avr_rt::qp16::Qp16Tables {
            max_iterations: 1,
            ..generated_qp16::QP16
        };
        if let Ok(mut capped) =
            qp16_law::Qp16Law::<S, NZ, NP, 4, _, _>::new(&cap1, qp16_law::kernel(), NX)
        {
            use generated_qp16::{QP16_THETA_LB, QP16_THETA_UB};
            let bx = (&QP16_THETA_LB, &QP16_THETA_UB);
            let mut out = |p: &[u8]| send(Kind::Bench, 0, p);
            let mut dec = FrameDecoder::new();
            let mut inp = |buf: &mut [u8; 40]| qp_check::recv_bench(&mut dec, rx_pop, buf);
            qp_check::check(
                &mut rate_loop.law,
                &mut capped,
                bx,
                NX,
                &clock,
                &mut out,
                &mut inp,
            );
        }
    }

    let mut decoder = FrameDecoder::new();
    let mut seqs = SeqTracker::new();
    let mut fresh: Option<(u8, Command)> = None;
    let mut last_seq = 0u8;
    let mut reply_seq = 0u8;
    let mut overrun = false;
    // Extra solver cycles requested by a fault frame (feature `hil-faults`).
    let mut stall = 0u32;
    // Drop a tick that came during the boot.
    // SAFETY: clear TOV4 by writing a one.
    unsafe { write_volatile(TIFR4, 1) };
    // The output watchdog and the watchdog timer from here on (not during
    // the boot and the benchmark builds' runs before the loop).
    // SAFETY: OCIE4B; its handler's state is a static byte.
    unsafe { write_volatile(TIMSK4, 1 << 2) };
    watchdog(WATCHDOG_64MS);
    loop {
        watchdog_reset();
        // Idle: decode bytes until the next 50 Hz tick.
        // SAFETY: TIFR4 read; TOV4 is bit 0.
        while unsafe { read_volatile(TIFR4) } & 1 == 0 {
            drain_rx(&mut decoder, &mut seqs, &mut fresh, &mut stall);
        }
        let t0 = clock.now();
        // SAFETY: clear TOV4 by writing a one.
        unsafe { write_volatile(TIFR4, 1) };
        // After an overrun the tick was already pending and the loop above
        // did not run: the bytes that came meanwhile (this period's
        // command among them) are still in the ring.
        drain_rx(&mut decoder, &mut seqs, &mut fresh, &mut stall);
        #[cfg(not(feature = "no-fgm"))]
        rate_loop.law.deadline.restart_at(t0);
        #[cfg(all(feature = "hil-faults", not(feature = "no-fgm")))]
        {
            rate_loop.law.deadline.extra = core::mem::take(&mut stall);
        }
        #[cfg(all(feature = "hil-faults", feature = "no-fgm"))]
        {
            rate_loop.law.extra = core::mem::take(&mut stall);
        }
        let _ = decoder.reset(); // inter-frame timeout: drop a half frame
        let cmd = fresh.take();
        if let Some((s, _)) = cmd {
            last_seq = s;
        }
        let out = rate_loop.period(cmd.as_ref().map(|(_, c)| c), &clock);
        set_pwm(&out.pwm);
        let mut st = out.status;
        if overrun {
            st |= status::OVERRUN;
        }
        let reply = Reply {
            cmd_seq: last_seq,
            status: st,
            pwm: out.pwm,
            kalman_cycles: out.kalman_cycles,
            solver_cycles: out.solver_cycles,
            period_cycles: clock.now().wrapping_sub(t0),
            iterations: out.iterations,
            frame_errors: decoder.errors,
        };
        send(Kind::Reply, reply_seq, &reply.to_payload());
        reply_seq = reply_seq.wrapping_add(1);
        // A tick that came while we were busy is a missed deadline.
        // SAFETY: TIFR4 read.
        overrun = unsafe { read_volatile(TIFR4) } & 1 != 0;
        let _ = read_volatile_sreg();
    }
}

/// Decodes the received bytes: the newest accepted command goes to
/// `fresh`; with `hil-faults`, a fault request's extra solver cycles to
/// `stall` (a hang request does not return).
#[cfg_attr(not(feature = "hil-faults"), allow(unused_variables))]
fn drain_rx(
    decoder: &mut FrameDecoder,
    seqs: &mut SeqTracker,
    fresh: &mut Option<(u8, Command)>,
    stall: &mut u32,
) {
    while let Some(b) = rx_pop() {
        if let Some(Ok(f)) = decoder.push(b) {
            #[cfg(feature = "hil-faults")]
            if f.kind == Kind::Bench {
                *stall = faults::request(f.payload());
            }
            if let Ok(c) = Command::from_frame(&f) {
                if seqs.accept(f.seq) {
                    *fresh = Some((f.seq, c));
                }
            }
        }
    }
}

#[inline(always)]
fn read_volatile_sreg() -> u8 {
    // SAFETY: reading SREG has no side effects.
    unsafe { read_volatile(SREG) }
}

/// The explicit MPC law of the `empc` builds.
#[cfg(all(feature = "empc-check", not(feature = "empc-ns2")))]
type EmpcLaw16 = kestrel_avr_rt::explicit::tree16::Empc16Law<
    S,
    FarTable,
    NP,
    4,
    { generated_empc::EMPC16_ROWS },
>;

/// The explicit MPC law of the `empc-ns2` builds.
#[cfg(all(feature = "empc-check", feature = "empc-ns2"))]
type EmpcLaw16 = kestrel_avr_rt::explicit::tree16::Empc16Law<
    S,
    kestrel_avr_rt::progmem::FarChunks<{ generated_empc_ns2::EMPC_NS2_CHUNKS }>,
    NP,
    4,
    64,
>;

/// Parameters evaluated by [`empc_check`].
#[cfg(feature = "empc-check")]
const EMPC_CHECK_SAMPLES: u16 = 200;

/// Evaluates the tree (the raw walk from quantised parameters) at
/// `EMPC_CHECK_SAMPLES` pseudo-random parameters in the box and sends, per
/// parameter, one Bench-kind frame of 30 bytes: index (u16), law (u16,
/// 0xFFFF for an error), nodes (u16), cycles (u32), the 4 outputs (i32),
/// then the cycles of the whole law (`ControlLaw::control`) near there
/// (u32; at `Empc16Law::check_bits`: on the grid, off it for odd samples,
/// beyond the box for every fourth), its nodes (u16) and the wrapping sum
/// of its outputs' Q15.16 bits (u32).
#[cfg(feature = "empc-check")]
#[inline(never)] // its own frame, not main's (the AVR's 8 kB of RAM)
fn empc_check(law: &mut EmpcLaw16, clock: &Timer1Clock) {
    use kestrel_core::ControlLaw;
    let mut seed = 0x2545_f491u32;
    for i in 0..EMPC_CHECK_SAMPLES {
        let q = law.box_sample(&mut seed);
        let t0 = clock.now();
        let r = core::hint::black_box(law.evaluate_raw(core::hint::black_box(&q)));
        let cycles = clock.now().wrapping_sub(t0);
        // The whole law (theta as the loop's scalar, quantisation, walk,
        // outputs) near the same parameter: theta_j = q_j 2^(s_j - 16),
        // off the grid or beyond the box for some samples (`check_bits`).
        let bits = law.check_bits(&q, i);
        // f32 builds: the values with bits below Q15.16 flipped and some
        // non-finite (`check_f32`), for the routine's own f32 conversion.
        #[cfg(not(any(feature = "fixed", feature = "fixed-mac")))]
        let theta: [S; NP] = law.check_f32(&bits, i);
        #[cfg(any(feature = "fixed", feature = "fixed-mac"))]
        let theta: [S; NP] = core::array::from_fn(|j| S::from_q16(bits[j]));
        let theta = core::hint::black_box(theta);
        let mut u = [S::ZERO; 4];
        let t1 = clock.now();
        let _ = core::hint::black_box(law.control(&theta[..NX], &theta[NX..], &mut u));
        let control_cycles = clock.now().wrapping_sub(t1);
        let steps2 = kestrel_avr_rt::control::LawInfo::iterations(law);
        let u_sum = u
            .iter()
            .fold(0u32, |a, v| a.wrapping_add(v.to_q16().unwrap_or(0) as u32));
        let mut p = [0u8; 36];
        p[0..2].copy_from_slice(&i.to_le_bytes());
        let (lw, steps, z) = match r {
            Ok(raw) => (raw.law, raw.steps, raw.z),
            Err(_) => (0xFFFF, 0, [0; 4]),
        };
        p[2..4].copy_from_slice(&lw.to_le_bytes());
        p[4..6].copy_from_slice(&steps.to_le_bytes());
        p[6..10].copy_from_slice(&cycles.to_le_bytes());
        for (k, zk) in z.iter().enumerate() {
            p[10 + 4 * k..14 + 4 * k].copy_from_slice(&zk.to_le_bytes());
        }
        p[26..30].copy_from_slice(&control_cycles.to_le_bytes());
        p[30..32].copy_from_slice(&steps2.to_le_bytes());
        p[32..36].copy_from_slice(&u_sum.to_le_bytes());
        send(Kind::Bench, i as u8, &p);
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // Outputs to the safe pulses and stop (the watchdog resets the MCU).
    set_pwm(&SafeOutput::default().pwm(&PwmLimits::default()));
    loop {}
}


/// Times kestrel-fgm's solver with `k` iterations for each `k` in `ks` and
/// sends one Bench frame per count (synthetic but representative tables:
/// dense, contractive, all entries non-zero so soft-float timing is typical).
#[cfg(feature = "fgm-bench")]
fn fgm_bench(clock: &Timer1Clock) {
    use kestrel_avr_rt::frame::Bench;
    use kestrel_fgm::{FgmTables, FgmWorkspace, Start};
    const N: usize = 4;
    const P: usize = 9;
    let mut seed = 0x2545_f491u32;
    let mut rnd = move |scale: f32| {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let u = (seed >> 8) as f32 / (1u32 << 24) as f32; // [0, 1)
        S::from_f32_fast(scale * (u - 0.5) + scale * 0.01)
    };
    let t: FgmTables<S, N, P, 1> = FgmTables {
        m: Matrix::from_fn(|i, j| {
            if i == j {
                rnd(0.2) + S::from_f32_fast(0.5)
            } else {
                rnd(0.3)
            }
        }),
        k_theta: Matrix::from_fn(|_, _| rnd(1.0)),
        k0: core::array::from_fn(|_| rnd(0.5)),
        lo_theta: Matrix::from_fn(|_, _| rnd(0.1)),
        lo0: core::array::from_fn(|_| rnd(0.2) - S::from_f32_fast(2.0)),
        hi_theta: Matrix::from_fn(|_, _| rnd(0.1)),
        hi0: core::array::from_fn(|_| rnd(0.2) + S::from_f32_fast(2.0)),
        d: core::array::from_fn(|_| rnd(0.5) + S::from_f32_fast(1.0)),
        d_inv: core::array::from_fn(|_| rnd(0.5) + S::from_f32_fast(1.0)),
        betas: [S::from_f32_fast(0.6)],
        iterations: 56,
        warm_iterations: 20,
        shift: 0,
    };
    let theta: [S; P] = core::array::from_fn(|_| rnd(1.0));

    // A stationary-Kalman-sized step with kestrel-core's kernels (thesis
    // size: 5 states, 4 inputs, 3 outputs): x <- x + K (y - C x), then
    // x <- A x + B u. kestrel-kalman has no run-time step yet; this times
    // the same arithmetic.
    {
        use kestrel_core::StateSpace;
        let ss = StateSpace::<S, 5, 4, 3>::new(
            Matrix::from_fn(|i, j| {
                if i == j {
                    rnd(0.2) + S::from_f32_fast(0.7)
                } else {
                    rnd(0.2)
                }
            }),
            Matrix::from_fn(|_, _| rnd(0.02)),
            Matrix::from_fn(|_, _| rnd(1.0)),
            Matrix::from_fn(|_, _| <S as kestrel_core::Scalar>::ZERO),
            0.02,
        );
        let kgain: Matrix<S, 5, 3> = Matrix::from_fn(|_, _| rnd(0.5));
        let mut x: [S; 5] = core::array::from_fn(|_| rnd(1.0));
        let y: [S; 3] = core::array::from_fn(|_| rnd(1.0));
        let u: [S; 4] = core::array::from_fn(|_| rnd(100.0));
        let t0 = clock.now();
        let (ss, kgain, y, u) = core::hint::black_box((&ss, &kgain, &y, &u));
        let yhat = ss.c.mul_vec(&x);
        let innov = kestrel_core::sub(y, &yhat);
        kgain.mul_vec_acc(&innov, &mut x);
        x = ss.step(&x, u);
        core::hint::black_box(&x);
        let cycles = clock.now().wrapping_sub(t0);
        let b = Bench {
            id: 100,
            ok: 1,
            iterations: 1,
            n: 5,
            p: 3,
            cycles,
        };
        send(Kind::Bench, 100, &b.to_payload());
    }

    // The same step with 16-bit coefficients (Q2.13) and Q16 states through
    // the narrower 32 x 16 MAC (kestrel_avr_rt::mac::dot_q16_i16).
    {
        use kestrel_avr_rt::mac::dot_q16_i16;
        let mut lcg = 0x1357_9bdfu32;
        let mut coef = move || {
            lcg = lcg.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((lcg >> 16) as i16) >> 3
        };
        let a: [[i16; 5]; 5] = core::array::from_fn(|_| core::array::from_fn(|_| coef()));
        let bm: [[i16; 4]; 5] = core::array::from_fn(|_| core::array::from_fn(|_| coef()));
        let c: [[i16; 5]; 3] = core::array::from_fn(|_| core::array::from_fn(|_| coef()));
        let k: [[i16; 3]; 5] = core::array::from_fn(|_| core::array::from_fn(|_| coef()));
        let mut x: [i32; 5] = core::array::from_fn(|i| (i as i32 - 2) * 40_000);
        let y: [i32; 3] = [30_000, -20_000, 10_000];
        let u: [i32; 4] = [1_000_000, -2_000_000, 500_000, 0];
        let q = |v: i64| ((v + (1 << 12)) >> 13) as i32; // back to Q16
        let t0 = clock.now();
        let (a, bm, c, k, y, u) = core::hint::black_box((&a, &bm, &c, &k, &y, &u));
        let innov: [i32; 3] = core::array::from_fn(|i| y[i] - q(dot_q16_i16(&x, &c[i])));
        for i in 0..5 {
            x[i] += q(dot_q16_i16(&innov, &k[i]));
        }
        let xn: [i32; 5] =
            core::array::from_fn(|i| q(dot_q16_i16(&x, &a[i]) + dot_q16_i16(u, &bm[i])));
        core::hint::black_box(&xn);
        let cycles = clock.now().wrapping_sub(t0);
        let b = Bench {
            id: 101,
            ok: 1,
            iterations: 1,
            n: 5,
            p: 3,
            cycles,
        };
        send(Kind::Bench, 101, &b.to_payload());
    }

    // Micro-benchmarks of the 16-bit kernels, 64 calls each (ids 102-105):
    // round_shift by a run-time shift, mul_q15, a 4-term Row16 dot, and
    // one Fgm16-sized row step (dot + round_shift).
    {
        use kestrel_avr_rt::kalman16::{Row16, mul_q15, round_shift};
        let row = core::hint::black_box(Row16::new([12345i16, -23456, 7890, -321], 15, 0));
        let v = core::hint::black_box([98_304i32, -40_000, 1_234_567, -7]);
        let shift = core::hint::black_box(19u8);
        let mut acc = 0i32;
        let mut time = |id: u8, f: &mut dyn FnMut(i32) -> i32| {
            let t0 = clock.now();
            for k in 0..64i32 {
                acc = acc.wrapping_add(f(core::hint::black_box(k)));
            }
            let cycles = clock.now().wrapping_sub(t0);
            let b = Bench { id, ok: 1, iterations: 64, n: 4, p: 1, cycles };
            send(Kind::Bench, id, &b.to_payload());
        };
        time(102, &mut |k| round_shift(core::hint::black_box(0x1234_5678_9abc + k as i64), shift));
        time(103, &mut |k| mul_q15(core::hint::black_box(0x0123_4567 + k), -23456));
        time(104, &mut |k| {
            let mut w = v;
            w[0] += k;
            core::hint::black_box(row.dot(&w)) as i32
        });
        time(105, &mut |k| {
            let mut w = v;
            w[0] += k;
            row.apply(&w)
        });
        core::hint::black_box(acc);
    }

    let mut ws = FgmWorkspace::<S, N>::new();
    for (id, k) in [1u16, 12, 56, 91].into_iter().enumerate() {
        let t0 = clock.now();
        let r = core::hint::black_box(t.solve_with(
            core::hint::black_box(&theta),
            Start::Cold,
            k as usize,
            &mut ws,
        ));
        let cycles = clock.now().wrapping_sub(t0);
        let b = Bench {
            id: id as u8,
            ok: r.is_ok() as u8,
            iterations: k,
            n: N as u8,
            p: P as u8,
            cycles,
        };
        send(Kind::Bench, id as u8, &b.to_payload());
    }
}
