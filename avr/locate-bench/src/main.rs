//! Cycles of kestrel-empc's candidate-list point location on the
//! ATmega2560 (16 MHz): the tables in program memory (4 kB statics in
//! `.text.kestrel_tables`, read with `ELPM`) through
//! kestrel-avr-rt's `locate::FlashLists` (the chunks, contiguous, read as
//! one `FarTable`), evaluated by
//! `kestrel_empc::evaluate_lists` in `f32` (avr-libc's float routines, as
//! avr/firmware) or `kestrel_avr_rt::mac::Q16Mac` (Q15.16, the hardware
//! multiplier), as the generated file says, at the parameters of the generated file, each timed with
//! Timer1 (prescaler 1, overflow interrupt).
//!
//! The tables and parameters come from the file named by the build-time
//! environment variable `KESTREL_LOCATE_GENERATED` (written by
//! kestrel-avr-rt's `tests/locate_avr.rs`, which builds this program,
//! runs it in simavr and compares every answer with the host's).
//!
//! USART0 lines: `INIT <0 ok | 1 bad table | 2 chunks not contiguous>`;
//! `CAL ram reads flash`, the cycles of 10 affine rows of `p` entries in
//! RAM, of reading as many 4-byte numbers from the table and of 10 rows
//! evaluated from the table; per parameter `L i law steps tests cycles
//! z0 .. z3` (the outputs' bits) or `L i ERR`; `END` (`PANIC file line`
//! on a panic); then it sleeps with interrupts off (simavr ends).
#![no_std]
#![no_main]
#![feature(abi_avr_interrupt, asm_experimental_arch)]

use kestrel_avr_rt::bench_uart::{self, num, stop, tx};
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::cycles::timer1::{self, Timer1Clock};
use kestrel_avr_rt::locate::{FlashLists, ListLayout};
use kestrel_avr_rt::progmem::{FarTable, TableRead};
use kestrel_core::Scalar;
use kestrel_empc::{ListAccess, evaluate_lists};

/// The raw bits of a number (the outputs are sent as bits).
trait Bits {
    fn bits(self) -> u32;
}
impl Bits for f32 {
    fn bits(self) -> u32 {
        self.to_bits()
    }
}
impl Bits for kestrel_avr_rt::mac::Q16Mac {
    fn bits(self) -> u32 {
        self.0 as u32
    }
}

// S (the scalar), LAYOUT, P, K, N_CHUNKS, CHUNK_BYTES, chunks(), THETAS.
include!(env!("KESTREL_LOCATE_GENERATED"));

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
    // The chunks are 4 kB statics of one section, laid out in order: read
    // them as one table (a single `FarTable`, no chunk arithmetic per
    // read). Checked here; a build where the linker reordered them stops.
    let parts = chunks();
    let start = parts.first().map_or(0, |c| c.address());
    let mut len = 0u32;
    for (i, c) in parts.iter().enumerate() {
        if c.address() != start + i as u32 * CHUNK_BYTES {
            tx(b"INIT 2\n");
            stop()
        }
        len += c.len_bytes();
    }
    // SAFETY: `start..start + len` is the chunks' flash, contiguous (checked).
    let table = unsafe { FarTable::from_raw(start, len) };
    let Ok(lists) = FlashLists::<_, S>::new(table, LAYOUT) else {
        tx(b"INIT 1\n");
        stop()
    };
    tx(b"INIT 0\n");
    // Calibration: 10 affine rows of P entries in RAM (f32 mul-adds), and
    // the same rows read from the flash table by the accessor.
    let row = core::hint::black_box([S::from_f64(0.37); 16]);
    let th = core::hint::black_box([S::from_f64(0.11); P]);
    let t0 = clock.now();
    let mut acc = S::ZERO;
    for _ in 0..10 {
        let row = core::hint::black_box(row);
        let mut a = row[P % 16];
        for (g, t) in row.iter().zip(&th) {
            a = a.mul_add(*g, *t);
        }
        acc = acc + a;
    }
    let ram = clock.now().wrapping_sub(t0);
    let mut probe = [0u8; 4];
    let t0 = clock.now();
    for i in 0..10 * (P as u32 + 1) {
        let b: [u8; 4] = table_read(&table, i).unwrap_or([0; 4]);
        probe[0] ^= b[0];
    }
    let reads = clock.now().wrapping_sub(t0);
    core::hint::black_box(probe);
    let t0 = clock.now();
    for r in 0..10usize {
        acc = acc + ListAccess::row_value(&lists, r, &th).unwrap_or(S::ZERO);
    }
    let flash = clock.now().wrapping_sub(t0);
    core::hint::black_box(acc);
    tx(b"CAL");
    num(ram);
    num(reads);
    num(flash);
    tx(b"\n");
    let mut scratch = [S::ZERO; P];
    let mut z = [S::ZERO; K];
    for (i, theta) in THETAS.iter().enumerate() {
        let theta = core::hint::black_box(theta);
        let t0 = clock.now();
        let e = evaluate_lists(&lists, theta, &mut scratch, &mut z);
        let cycles = clock.now().wrapping_sub(t0);
        tx(b"L");
        num(i as u32);
        match e {
            Ok(e) => {
                num(u32::from(e.law));
                num(u32::from(e.steps));
                num(u32::from(e.tests));
                num(cycles);
                for v in z {
                    num(v.bits());
                }
            }
            Err(_) => tx(b" ERR"),
        }
        tx(b"\n");
    }
    tx(b"END\n");
    stop()
}

/// 4 bytes at `4 i` of the flash table (calibration).
fn table_read(t: &FarTable, i: u32) -> Option<[u8; 4]> {
    core::hint::black_box(t).read_array::<4>(4 * i)
}

/// Sends `PANIC file line` and stops.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    bench_uart::panic_report(info)
}
