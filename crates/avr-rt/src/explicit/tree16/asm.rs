//! The period on the AVR's assembly routine (`walk_avr`), for narrow
//! tables in flash: the context's per-call fields, the call, and its
//! results as the law's. AVR only.

use super::law::{Empc16Law, Raw};
use crate::output::RtScalar;
use crate::progmem::TableRead;
use kestrel_core::Error;

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize>
    Empc16Law<S, T, P, NU, R>
{
    /// The assembly walk (`explicit/tree16/walk_avr.rs`, AVR only) when the table is in flash:
    /// with `bits`, `theta` is quantised from those Q15.16 values first
    /// (the outside flag is returned through `self.outside`); the outputs
    /// rounded and shifted right by `out_shift` bits; `None`: the table is
    /// not in flash.
    #[cfg(target_arch = "avr")]
    #[inline(always)]
    pub(super) fn walk_asm(
        &mut self,
        bits: Option<&[i32; P]>,
        out_shift: u8,
    ) -> Option<Result<Raw<NU>, Error>> {
        let mut z = [0i32; NU];
        let status = self.run_asm(bits.map(|b| (&b[..], &[][..])), false, out_shift, &mut z)?;
        Some(if status == 0 {
            Ok(Raw {
                z,
                law: u16::from(self.scratch.ctx.law),
                steps: self.scratch.ctx.steps,
            })
        } else {
            Err(Error::OutOfRange)
        })
    }

    /// One call of the assembly routine (`explicit/tree16/walk_avr.rs`) with the
    /// outputs into `z`: its status (0; 2 for a non-finite `f32` value),
    /// the outside count updated; `None`: the table is not in flash or
    /// wide. `bits` are Q15.16 values, or with `f32_theta` `f32` bit
    /// patterns.
    #[cfg(target_arch = "avr")]
    #[inline(always)]
    fn run_asm(
        &mut self,
        bits: Option<(&[i32], &[i32])>,
        f32_theta: bool,
        out_shift: u8,
        z: &mut [i32; NU],
    ) -> Option<u8> {
        if self.tree.layout.wide {
            return None; // the assembly reads the narrow layout
        }
        self.tree.table.flash_address()?;
        // The context's constant fields were written by `new` (`ctx_block`);
        // the pointers (the law may have moved since), the stamp and the
        // output shift are this call's.
        let cache = self.scratch.cache.as_mut_ptr() as usize as u16;
        let params = self.param_bytes.as_ptr() as usize as u16;
        let ctx = &mut self.scratch.ctx;
        ctx.cache = cache;
        // The P values: q16's first nx, then q16b's (the caller checked
        // that the two hold P).
        let (first, rest) = bits.unwrap_or((&[], &[]));
        ctx.q16 = if bits.is_some() {
            first.as_ptr() as usize as u16
        } else {
            0
        };
        ctx.q16b = rest.as_ptr() as usize as u16;
        ctx.nx = first.len() as u8;
        ctx.params = params;
        ctx.out = z.as_mut_ptr() as usize as u16;
        ctx.period = self.period;
        ctx.out_shift = out_shift;
        ctx.f32_theta = u8::from(f32_theta);
        // SAFETY: `ctx` is the start of this law's scratch (`repr(C)`: the
        // context, theta, then the cache) and points at its parameter
        // bytes, `z` (NU values) and the bits (P values in two slices); the routine
        // writes only the scratch (row indices checked against
        // `n_rows <= R`), `z` and the context, and reads flash inside the
        // table (indices checked).
        let status = unsafe { super::walk_avr::kestrel_empc16_eval(ctx) };
        if self.scratch.ctx.outside != 0 {
            self.outside = self.outside.saturating_add(1);
        }
        Some(status)
    }

    /// [`Self::solve`] on the AVR's assembly routine (`None`: the table is
    /// not in flash, wide, or has a scale below 16).
    #[cfg(target_arch = "avr")]
    #[inline(always)]
    pub(super) fn solve_asm(
        &mut self,
        bits: (&[i32], &[i32]),
        f32_theta: bool,
        u: &mut [S],
    ) -> Option<Result<(), Error>> {
        let k = self.tree.layout.scale;
        if k < 16 {
            return None;
        }
        let mut z = [0i32; NU];
        let status = self.run_asm(Some(bits), f32_theta, k - 16, &mut z)?;
        match status {
            0 => {}
            2 => return Some(Err(Error::NonFinite)),
            _ => return Some(Err(Error::OutOfRange)),
        }
        self.steps = self.scratch.ctx.steps;
        for (ui, zi) in u.iter_mut().zip(z) {
            *ui = S::from_q16(zi);
        }
        Some(Ok(()))
    }
}
