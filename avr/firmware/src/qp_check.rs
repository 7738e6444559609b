//! The exact MPC's on-target check (features `qp-check`, `qp16-check`):
//! the law at pseudo-random parameters of the whole parameter box, for
//! the HIL test to solve the same parameters on the host.

use kestrel_avr_rt::control::LawInfo;
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::frame::{FrameDecoder, Kind};
use kestrel_avr_rt::output::RtScalar;
use kestrel_core::ControlLaw;

/// Parameters of each part of [`check`].
pub const CHECK_SAMPLES: u16 = 150;

/// The check, three parts of [`CHECK_SAMPLES`] solves of the whole law
/// (`ControlLaw::control`: set-up, solve, first move):
///
/// 1. `law` with cold starts (restarted before each solve) at
///    pseudo-random parameters in the box `[lb, ub]`;
/// 2. `law` as it flies (warm starts for `qp`, cold every period for the
///    qp16 builds) along a random walk in the box (each step at most 5 %
///    of the box's width per parameter);
/// 3. `capped` (the same law with the iteration cap 1 and cold starts) at
///    pseudo-random parameters: the fallback wherever two or more
///    active-set changes are needed.
///
/// Parameters lie on a grid of 2^-8 (exact in f32 and in Q15.16). Per
/// solve it sends two frames through `send`: the index and the
/// parameter's `P` f32 (`2 + 4 P` bytes), then the index, the law's
/// iterations (its `FALLBACK` bit; 0xFFFF for an error), the cycles and
/// the four outputs as f32 (24 bytes).
///
/// Then it serves the host's parameters for ever (the check builds do not
/// fly): each payload of `2 + 4 P` bytes that `recv` gives (an index, the
/// parameter's `P` f32) is solved by `law`, from a cold start unless bit
/// 15 of the index is set (then, for a warm-starting law, warm from the
/// previous request's active set), and answered with a result frame as
/// above.
#[inline(never)] // its own frame, not main's
pub fn check<S, L, K, const P: usize>(
    law: &mut L,
    capped: &mut K,
    box_f32: (&[f32; P], &[f32; P]),
    nx: usize,
    clock: &impl CycleClock,
    send: &mut dyn FnMut(&[u8]),
    recv: &mut dyn FnMut(&mut [u8; 40]) -> usize,
) -> !
where
    S: RtScalar,
    L: ControlLaw<Scalar = S> + LawInfo,
    K: ControlLaw<Scalar = S> + LawInfo,
{
    let (lb, ub) = box_f32;
    let mut seed = 0x2545_f491u32;
    let mut uniform = move || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 // [0, 1)
    };
    let grid = |v: f32| (v * 256.0) as i32 as f32 / 256.0;
    let mut theta = [0f32; P];
    for i in 0..3 * CHECK_SAMPLES {
        let part = i / CHECK_SAMPLES;
        for (j, t) in theta.iter_mut().enumerate() {
            let (lo, hi) = (lb[j], ub[j]);
            *t = grid(if part == 1 && i > CHECK_SAMPLES {
                // max/min, not f32::clamp: its assertion is a panic path.
                (*t + (hi - lo) * 0.05 * (2.0 * uniform() - 1.0)).max(lo).min(hi)
            } else {
                lo + (hi - lo) * uniform()
            });
        }
        if part == 0 || i == CHECK_SAMPLES {
            law.restart();
        }
        let mut a = [0u8; 40];
        a[0..2].copy_from_slice(&i.to_le_bytes());
        for (j, t) in theta.iter().enumerate() {
            if let Some(b) = a.get_mut(2 + 4 * j..6 + 4 * j) {
                b.copy_from_slice(&t.to_le_bytes());
            }
        }
        send(a.get(..2 + 4 * P).unwrap_or(&a));
        let th: [S; P] = core::array::from_fn(|j| S::from_f32_fast(theta[j]));
        let (iterations, cycles, u) = if part == 2 {
            solve_one(capped, &th, nx, clock)
        } else {
            solve_one(law, &th, nx, clock)
        };
        send(&result(i, iterations, cycles, &u));
    }
    let mut req = [0u8; 40];
    loop {
        if recv(&mut req) != 2 + 4 * P {
            continue;
        }
        let i = u16::from_le_bytes([req[0], req[1]]);
        let th: [S; P] = core::array::from_fn(|j| {
            let b = req.get(2 + 4 * j..6 + 4 * j).unwrap_or(&[0; 4]);
            S::from_f32_fast(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        });
        if i & 0x8000 == 0 {
            law.restart();
        }
        let (iterations, cycles, u) = solve_one(law, &th, nx, clock);
        send(&result(i, iterations, cycles, &u));
    }
}

/// A result frame's payload: index, iterations, cycles, the four outputs.
fn result<S: RtScalar>(i: u16, iterations: u16, cycles: u32, u: &[S; 4]) -> [u8; 24] {
    let mut b = [0u8; 24];
    b[0..2].copy_from_slice(&i.to_le_bytes());
    b[2..4].copy_from_slice(&iterations.to_le_bytes());
    b[4..8].copy_from_slice(&cycles.to_le_bytes());
    for (k, v) in u.iter().enumerate() {
        b[8 + 4 * k..12 + 4 * k].copy_from_slice(&v.to_f32().to_le_bytes());
    }
    b
}

/// One timed call of `law` at `theta`: its iterations (0xFFFF for an
/// error), cycles and outputs.
#[inline(never)]
fn solve_one<S: RtScalar, L: ControlLaw<Scalar = S> + LawInfo, const P: usize>(
    law: &mut L,
    theta: &[S; P],
    nx: usize,
    clock: &impl CycleClock,
) -> (u16, u32, [S; 4]) {
    let th = core::hint::black_box(*theta);
    let mut u = [S::ZERO; 4];
    let t0 = clock.now();
    let r = core::hint::black_box(law.control(&th[..nx], &th[nx..], &mut u));
    let cycles = clock.now().wrapping_sub(t0);
    let iterations = if r.is_ok() { law.iterations() } else { 0xFFFF };
    (iterations, cycles, u)
}

/// The next Bench-kind frame's payload from the bytes `pop` gives (the
/// receive ring) into `buf` (its length), or 0 when no whole frame is
/// there yet.
pub fn recv_bench(
    dec: &mut FrameDecoder,
    mut pop: impl FnMut() -> Option<u8>,
    buf: &mut [u8; 40],
) -> usize {
    while let Some(b) = pop() {
        if let Some(Ok(f)) = dec.push(b) {
            let p = f.payload();
            if f.kind == Kind::Bench && p.len() <= buf.len() {
                buf[..p.len()].copy_from_slice(p);
                return p.len();
            }
        }
    }
    0
}
