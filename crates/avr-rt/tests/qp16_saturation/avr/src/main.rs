//! kestrel-avr-rt's `qp16` assembly routines on crafted inputs, on the
//! ATmega2560: the generated file named by the build-time environment
//! variable `KESTREL_SAT_GENERATED` (written by kestrel-avr-rt's
//! `tests/qp16_saturation.rs`, which builds this program, runs it in simavr
//! and compares every line with the host's run of the same functions)
//! defines `fn cases()`, one call of the functions below per case.
//!
//! Operands are built on the stack (a bulk value repeated, then a tail),
//! so long sums cost no RAM for tables; each case function is
//! `#[inline(never)]` so that their stack frames are not added up. USART0 lines: `INIT`, one `C id
//! v..` per case (each value as the `u32` of its bits), `END` (`PANIC file
//! line` on a panic); then it sleeps with interrupts off (simavr ends).
#![no_std]
#![no_main]
// Each generated program uses some of the case functions.
#![allow(dead_code)]

use kestrel_avr_rt::bench_uart::{self, num, stop, tx};
use kestrel_avr_rt::mac::Row16;
use kestrel_avr_rt::qp16::probe::{self, PassVar};
use kestrel_avr_rt::qp16::{mac_round, rows_round};

include!(env!("KESTREL_SAT_GENERATED"));

/// `out[..len]`: `bulk` then `tail` (the last `tail.len()` entries).
#[inline(never)]
fn fill(out: &mut [i32], bulk: i32, tail: &[i32]) {
    let cut = out.len().saturating_sub(tail.len());
    for (i, o) in out.iter_mut().enumerate() {
        *o = if i < cut {
            bulk
        } else {
            tail.get(i - cut).copied().unwrap_or(0)
        };
    }
}

fn head(id: u16) {
    tx(b"C");
    num(u32::from(id));
}

fn nums(v: &[i32]) {
    for x in v {
        num(*x as u32);
    }
}

/// The operands of the long sums (`mac`: `a` then `b`; `rows`: the data,
/// then `r`): a static buffer, not kilobytes of stack frame. (With such a
/// frame and `core::hint::black_box` on the shift, the pinned nightly's
/// AVR backend saved SREG in `r0` to reach a stack slot beyond the 6-bit
/// displacement while `r0` still held a product byte of the wrapper's
/// `rows k`: the wrapper then saw too short a slice and returned zeros.
/// No `black_box` here: the operands are built at run time anyway.)
static mut BUF: [i32; 8 * 64 + 64] = [0; 8 * 64 + 64];

/// The buffer (one case at a time).
fn buf() -> &'static mut [i32; 8 * 64 + 64] {
    // SAFETY: single-threaded, no interrupts; each case function takes the
    // buffer once and drops it before returning.
    unsafe { &mut *core::ptr::addr_of_mut!(BUF) }
}

/// A `mac_round` case: `n` terms, `a` is `ab` then `at`, `b` is `bb`
/// then `bt`.
struct Mac {
    id: u16,
    n: usize,
    ab: i32,
    at: &'static [i32],
    bb: i32,
    bt: &'static [i32],
    shift: u8,
}

/// Runs a `mac_round` case (the case by reference: with seven arguments,
/// some passed on the stack, the rows case read wrong operands on the AVR
/// once the program held all the cases; see docs/avr-qp.md).
#[inline(never)]
fn mac(c: &Mac) {
    let (a, b) = buf().split_at_mut(256);
    let n = c.n.min(256);
    fill(&mut a[..n], c.ab, c.at);
    fill(&mut b[..n], c.bb, c.bt);
    let r = mac_round(&a[..n], &b[..n], c.shift);
    head(c.id);
    nums(&[r]);
    tx(b"\n");
}

/// A `rows_round` case: `db.len()` rows of `k` terms, `r` is `rb` then
/// `rt`, row `i` is `db[i]` then `dt[i t..(i + 1) t]` (`t = rt.len()`).
struct Rows {
    id: u16,
    k: usize,
    shift: u8,
    rb: i32,
    rt: &'static [i32],
    db: &'static [i32],
    dt: &'static [i32],
}

/// Runs a `rows_round` case (by reference, as [`mac`]).
#[inline(never)]
fn rows(c: &Rows) {
    let (data, r) = buf().split_at_mut(8 * 64);
    let mut out = [0i32; 8];
    let (k, n) = (c.k.min(64), c.db.len().min(8));
    let t = c.rt.len();
    fill(&mut r[..k], c.rb, c.rt);
    for i in 0..n {
        let tail = c.dt.get(i * t..(i + 1) * t).unwrap_or(&[]);
        fill(&mut data[i * k..(i + 1) * k], c.db[i], tail);
    }
    rows_round(&data[..n * k], &r[..k], c.shift, &mut out[..n]);
    head(c.id);
    nums(&out[..n]);
    tx(b"\n");
}

/// `Row16::apply_all` of `rows` over `v`, then `Row16::add_all` onto `acc`.
#[inline(never)]
fn row16<const N: usize, const R: usize>(
    id: u16,
    rows: &[Row16<N>; R],
    v: &[i32; N],
    acc: [i32; R],
) {
    let got = Row16::apply_all(rows, v);
    let mut sum = acc;
    Row16::add_all(rows, v, &mut sum);
    head(id);
    nums(&got);
    nums(&sum);
    tx(b"\n");
}

/// `probe::members`: mask, count, residuals.
#[inline(never)]
fn members<const N: usize>(id: u16, var: [PassVar; N]) {
    let (mask, q, r) = probe::members(&var);
    head(id);
    nums(&[mask as i32, q as i32]);
    nums(&r);
    tx(b"\n");
}

/// `probe::stars`: the candidates' mask, then each record's `star`.
#[inline(never)]
fn stars<const N: usize>(id: u16, var: [PassVar; N], out: [i32; N], limit: i32) {
    let mut var = var;
    let cand = probe::stars(&mut var, &out, limit);
    head(id);
    nums(&[cand as i32]);
    for v in &var {
        nums(&[v.star]);
    }
    tx(b"\n");
}

/// `probe::scan`: the index and code, then each record's `w` and `nu`.
#[inline(never)]
fn scan<const N: usize>(id: u16, var: [PassVar; N], out: [i32; N], k: usize, tol: i32) {
    let mut var = var;
    let (best, code) = probe::scan(&mut var, &out, k, tol);
    head(id);
    nums(&[best as i32, i32::from(code)]);
    for v in &var {
        nums(&[v.w, v.nu]);
    }
    tx(b"\n");
}

/// A record (the generated cases' shorthand).
const fn var(unc: i32, lo: i32, hi: i32, star: i32, pos: u8, code: u8, nu: i32) -> PassVar {
    PassVar {
        unc,
        lo,
        hi,
        w: 0,
        star,
        pos,
        code,
        nu,
    }
}

#[unsafe(no_mangle)]
pub extern "C" fn main() -> ! {
    // SAFETY: USART0 is this program's alone.
    unsafe { bench_uart::init() };
    tx(b"INIT\n");
    cases();
    tx(b"END\n");
    stop()
}

/// Sends `PANIC file line` and stops.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    bench_uart::panic_report(info)
}
