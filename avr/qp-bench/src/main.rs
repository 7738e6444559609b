//! Cycles of kestrel-avr-rt's fixed-point dual active-set solver
//! (`qp16`) on the ATmega2560 (16 MHz): the tables (in RAM) and the
//! parameters come from the file named by the build-time environment
//! variable `KESTREL_QP_GENERATED` (written by kestrel-avr-rt's
//! `tests/qp_avr.rs`, which builds this program, runs it in simavr and
//! compares every answer with the host's run of the same code). Each
//! parameter is solved warm from the previous parameter's final active set
//! (its cold solve's), then cold, with the factor-updating kernel (`Qp16Solver`, modes 0 and
//! 1) and, where the generated file has per-set tables, with the per-set
//! kernel (`Qp16SetSolver`, modes 2 and 3), each timed with Timer1
//! (prescaler 1, overflow interrupt).
//!
//! USART0 lines: `INIT N P`; `CAL` with the cycles of a one-term and a
//! nine-term rounded MAC, of a pivot's reciprocal and of the unconstrained
//! solution (all rows); per parameter `Q i mode iterations active
//! cycles w0 .. w(N-1)` (mode 0/2 cold, 1/3 warm; `w` the raw Q15.16 bits) or
//! `Q i mode ERR code cycles w0 ..` (the fallback's bits); `END` (`PANIC
//! file line` on a panic); then it sleeps with interrupts off (simavr ends).
#![no_std]
#![no_main]
#![feature(abi_avr_interrupt, asm_experimental_arch)]

use core::ptr::{read_volatile, write_volatile};
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::cycles::timer1::{self, Timer1Clock};
use kestrel_avr_rt::qp16::{Qp16Error, Qp16Info, Qp16SetSolver, Qp16Solver, Qp16Start};

// N, P, TABLES, SETS (whether SET_TABLES are real), SET_TABLES, THETAS.
include!(env!("KESTREL_QP_GENERATED"));

const UCSR0A: *mut u8 = 0xC0 as *mut u8;
const UCSR0B: *mut u8 = 0xC1 as *mut u8;
const UCSR0C: *mut u8 = 0xC2 as *mut u8;
const UBRR0L: *mut u8 = 0xC4 as *mut u8;
const UBRR0H: *mut u8 = 0xC5 as *mut u8;
const UDR0: *mut u8 = 0xC6 as *mut u8;

/// Timer1 overflow: the cycle counter's high half.
#[unsafe(no_mangle)]
pub unsafe extern "avr-interrupt" fn __vector_20() {
    // SAFETY: called only as the TIMER1_OVF handler.
    unsafe { timer1::on_overflow() }
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

/// ` v` in decimal.
fn num(v: u32) {
    let mut buf = [b' '; 11];
    let mut i = buf.len();
    let mut v = v;
    loop {
        i -= 1;
        if let Some(b) = buf.get_mut(i) {
            *b = b'0' + (v % 10) as u8;
        }
        v /= 10;
        if v == 0 || i <= 1 {
            break;
        }
    }
    tx(buf.get(i - 1..).unwrap_or(&[]));
}

fn stop() -> ! {
    // SAFETY: ends the simulation (simavr: sleeping with interrupts off).
    unsafe { core::arch::asm!("cli", "sleep") };
    loop {}
}

#[unsafe(no_mangle)]
pub extern "C" fn main() -> ! {
    // SAFETY: one-time USART0 set-up, 250000 baud 8N1, transmit only.
    unsafe {
        write_volatile(UBRR0H, 0);
        write_volatile(UBRR0L, 3);
        write_volatile(UCSR0A, 0);
        write_volatile(UCSR0C, 0x06);
        write_volatile(UCSR0B, 1 << 3);
    }
    // SAFETY: Timer1 is ours; interrupts are still off.
    let clock = unsafe { Timer1Clock::start() };
    // SAFETY: enables the Timer1 overflow interrupt.
    unsafe { core::arch::asm!("sei") };
    tx(b"INIT");
    num(N as u32);
    num(P as u32);
    tx(b"\n");
    // Calibration: one and nine terms of the rounded MAC, a reciprocal,
    // one bound row of the tables.
    let a = core::hint::black_box([123_456_789i32; 9]);
    let b = core::hint::black_box([-987_654i32; 9]);
    let t0 = clock.now();
    let r1 = kestrel_avr_rt::qp16::mac_round(&a[..1], &b[..1], 20);
    let c1 = clock.now().wrapping_sub(t0);
    let t0 = clock.now();
    let r9 = kestrel_avr_rt::qp16::mac_round(&a, &b, 30);
    let c9 = clock.now().wrapping_sub(t0);
    let t0 = clock.now();
    let rc = kestrel_avr_rt::qp16::Recip::new(core::hint::black_box(123_456_789), 4);
    let cr = clock.now().wrapping_sub(t0);
    let t0 = clock.now();
    let rw = TABLES.unconstrained(&THETAS[0]);
    let cw = clock.now().wrapping_sub(t0);
    core::hint::black_box((r1, r9, rc, rw));
    tx(b"CAL");
    num(c1);
    num(c9);
    num(cr);
    num(cw);
    tx(b"\n");
    let mut solver = Qp16Solver::<N>::new();
    let mut per_set = Qp16SetSolver::<N>::new();
    #[cfg(feature = "profile")]
    let mut set_profile = [0u32; 7];
    let modes: &[u32] = if SETS { &[1, 0, 3, 2] } else { &[1, 0] };
    for (i, theta) in THETAS.iter().enumerate() {
        for &mode in modes {
            let start = if mode % 2 == 0 {
                Qp16Start::Cold
            } else {
                Qp16Start::Warm
            };
            let theta = core::hint::black_box(theta);
            let t0 = clock.now();
            #[cfg(feature = "profile")]
            // SAFETY: single-threaded read of the profile counters.
            let before = unsafe { *core::ptr::addr_of!(kestrel_avr_rt::qp16::QP16_PROFILE) };
            let r: Result<Qp16Info, Qp16Error> = if mode < 2 {
                solver.solve(&TABLES, theta, start)
            } else {
                per_set.solve(&TABLES, &SET_TABLES, theta, start)
            };
            #[cfg(feature = "profile")]
            if mode >= 2 {
                // SAFETY: as above.
                let after = unsafe { *core::ptr::addr_of!(kestrel_avr_rt::qp16::QP16_PROFILE) };
                for ((p, a), b) in set_profile.iter_mut().zip(after).zip(before) {
                    *p += a.wrapping_sub(b);
                }
            }
            let cycles = clock.now().wrapping_sub(t0);
            tx(b"Q");
            num(i as u32);
            num(mode);
            let w = match r {
                Ok(info) => {
                    num(u32::from(info.iterations));
                    num(u32::from(info.active));
                    if mode < 2 {
                        *solver.solution()
                    } else {
                        *per_set.solution()
                    }
                }
                Err(e) => {
                    tx(b" ERR");
                    num(match e {
                        Qp16Error::InvalidBounds => 1,
                        Qp16Error::Infeasible => 2,
                        Qp16Error::IterationLimit => 3,
                    });
                    if mode < 2 {
                        solver.fallback()
                    } else {
                        per_set.fallback()
                    }
                }
            };
            num(cycles);
            for v in w {
                num(v as u32);
            }
            tx(b"\n");
        }
    }
    #[cfg(feature = "profile")]
    {
        tx(b"PHASES");
        // SAFETY: the solves are done; single-threaded read.
        let all = unsafe { *core::ptr::addr_of!(kestrel_avr_rt::qp16::QP16_PROFILE) };
        for (v, p) in all.iter().zip(set_profile) {
            num(v.wrapping_sub(p));
        }
        tx(b"\n");
        tx(b"PHASES-PER-SET");
        for v in set_profile {
            num(v);
        }
        tx(b"\n");
    }
    tx(b"END\n");
    stop()
}

/// Sends `PANIC file line` and stops.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    tx(b"PANIC ");
    if let Some(l) = info.location() {
        tx(l.file().as_bytes());
        num(l.line());
    }
    tx(b"\n");
    stop()
}
