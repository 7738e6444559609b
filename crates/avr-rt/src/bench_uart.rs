//! Transmit-only USART0 for the cycle benches that run in simavr
//! (`avr/locate-bench`, `avr/qp-bench`, the qp16 saturation test's
//! program): 250,000 baud 8N1 at 16 MHz, busy-waiting, numbers in decimal,
//! a panic report, and the end of a simulation.
//!
//! Not for flight firmware (it blocks on the data register); the example
//! firmware has its own interrupt-driven framed protocol.

use core::ptr::{read_volatile, write_volatile};

const UCSR0A: *mut u8 = 0xC0 as *mut u8;
const UCSR0B: *mut u8 = 0xC1 as *mut u8;
const UCSR0C: *mut u8 = 0xC2 as *mut u8;
const UBRR0L: *mut u8 = 0xC4 as *mut u8;
const UBRR0H: *mut u8 = 0xC5 as *mut u8;
const UDR0: *mut u8 = 0xC6 as *mut u8;

/// Sets USART0 up: 250,000 baud 8N1 (16 MHz, `UBRR = 3`), transmit only.
///
/// # Safety
/// Takes USART0 over: nothing else may use it.
pub unsafe fn init() {
    // SAFETY: the caller gives us USART0; these are its registers.
    unsafe {
        write_volatile(UBRR0H, 0);
        write_volatile(UBRR0L, 3);
        write_volatile(UCSR0A, 0);
        write_volatile(UCSR0C, 0x06);
        write_volatile(UCSR0B, 1 << 3);
    }
}

/// Sends `bytes`, waiting for an empty data register before each.
pub fn tx(bytes: &[u8]) {
    for &b in bytes {
        // SAFETY: USART0 registers (set up by `init`); wait for an empty
        // data register.
        unsafe {
            while read_volatile(UCSR0A) & (1 << 5) == 0 {}
            write_volatile(UDR0, b);
        }
    }
}

/// Sends ` v` (a space, then `v` in decimal).
pub fn num(v: u32) {
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

/// Ends the simulation: simavr stops when the MCU sleeps with interrupts
/// off.
pub fn stop() -> ! {
    // SAFETY: disables interrupts and sleeps; nothing runs afterwards.
    unsafe { core::arch::asm!("cli", "sleep") };
    loop {}
}

/// Sends `PANIC file line` and ends the simulation: the body of a bench
/// program's `#[panic_handler]`.
pub fn panic_report(info: &core::panic::PanicInfo) -> ! {
    tx(b"PANIC ");
    if let Some(l) = info.location() {
        tx(l.file().as_bytes());
        num(l.line());
    }
    tx(b"\n");
    stop()
}
