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

use kestrel_avr_rt::bench_uart::{self, num, stop, tx};
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::cycles::timer1::{self, Timer1Clock};
use kestrel_avr_rt::qp16::{Qp16Error, Qp16Info, Qp16SetSolver, Qp16Solver, Qp16Start};

// N, P, TABLES, SETS (whether SET_TABLES are real), SET_TABLES, THETAS.
include!(env!("KESTREL_QP_GENERATED"));

/// Timer1 overflow: the cycle counter's high half.
#[unsafe(no_mangle)]
pub unsafe extern "avr-interrupt" fn __vector_20() {
    // SAFETY: called only as the TIMER1_OVF handler.
    unsafe { timer1::on_overflow() }
}

#[unsafe(no_mangle)]
pub extern "C" fn main() -> ! {
    // SAFETY: USART0 is this program's alone.
    unsafe { bench_uart::init() };
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
    bench_uart::panic_report(info)
}
