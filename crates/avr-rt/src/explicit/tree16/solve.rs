//! The law's period as a [`ControlLaw`] (and its [`LawInfo`]): checked
//! lengths, `theta = [x; r]` to Q15.16, then the assembly routine on the
//! AVR or the walk in Rust, and the outputs scaled back.

use super::law::Empc16Law;
use crate::law::LawInfo;
use crate::output::RtScalar;
use crate::progmem::TableRead;
use crate::shift::round_shift32;
use kestrel_core::{ControlLaw, Error, check_len};

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize> ControlLaw
    for Empc16Law<S, T, P, NU, R>
{
    type Scalar = S;
    crate::law::parametric_law_sizes!();
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        check_len(x, self.nx)?;
        check_len(r, P - self.nx)?;
        check_len(u, NU)?;
        self.solve(x, r, u)
    }
}

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize>
    Empc16Law<S, T, P, NU, R>
{
    /// One period from `theta = [x; r]` (checked lengths) in one frame of
    /// its own (conversion to Q15.16, quantisation, walk, outputs): inlined
    /// into the caller's large frame, every local costs a long
    /// stack-pointer adjustment on the AVR.
    #[inline(never)]
    fn solve(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        self.next_period();
        // Scalars stored as Q15.16 bits: the routine reads them in place;
        // f32: the routine reads their bits in place and converts them
        // itself (exactly as `to_q16`), no Q15.16 copy.
        #[cfg(target_arch = "avr")]
        if let (Some(xb), Some(rb)) = (S::as_q16_bits(x), S::as_q16_bits(r)) {
            if let Some(res) = self.solve_asm((xb, rb), false, u) {
                return res;
            }
        } else if let (Some(xb), Some(rb)) = (S::as_f32_bits(x), S::as_f32_bits(r)) {
            if let Some(res) = self.solve_asm((xb, rb), true, u) {
                return res;
            }
        }
        // theta = [x; r] as Q15.16 bits, in one pass.
        let mut bits = [0i32; P];
        for (b, t) in bits.iter_mut().zip(x.iter().chain(r)) {
            *b = t.to_q16().ok_or(Error::NonFinite)?;
        }
        // On the AVR with the table in flash: quantisation, walk and the
        // outputs in Q15.16 (scale >= 16) in one assembly routine.
        #[cfg(target_arch = "avr")]
        if let Some(r) = self.solve_asm((&bits[..], &[]), false, u) {
            return r;
        }
        self.solve_rust(&bits, u)
    }

    /// [`Self::solve`] in Rust (the host's path, and tables not in flash).
    #[inline(never)]
    fn solve_rust(&mut self, bits: &[i32; P], u: &mut [S]) -> Result<(), Error> {
        let k = self.tree.layout.scale;
        let (q, outside) = self.quantize_bits(bits);
        self.scratch.theta = q;
        if outside {
            self.outside = self.outside.saturating_add(1);
        }
        let raw = self.walk().ok_or(Error::OutOfRange)?;
        self.steps = raw.steps;
        if k >= 16 {
            let s = k - 16;
            for (ui, zi) in u.iter_mut().zip(raw.z) {
                *ui = S::from_q16(round_shift32(zi, s));
            }
        } else {
            outputs_up(&raw.z, 16 - k, u);
        }
        Ok(())
    }
}

/// Outputs of a table with fewer than 16 fraction bits: `z 2^s`, saturated.
#[cold]
#[inline(never)]
fn outputs_up<S: RtScalar, const NU: usize>(z: &[i32; NU], s: u8, u: &mut [S]) {
    for (ui, &zi) in u.iter_mut().zip(z) {
        *ui = S::from_q16(zi.saturating_mul(1 << s.min(30)));
    }
}

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize> LawInfo
    for Empc16Law<S, T, P, NU, R>
{
    /// The tree nodes visited in the last period.
    fn iterations(&self) -> u16 {
        self.steps
    }
}
