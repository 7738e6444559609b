//! Test instrumentation of [`Empc16Law`]: the on-target check's samples
//! (the same sequence on every target) and the cache's row count.

use super::law::Empc16Law;
use crate::output::RtScalar;
use crate::progmem::TableRead;

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize>
    Empc16Law<S, T, P, NU, R>
{
    /// A pseudo-random quantised parameter in the box (a 32-bit LCG in
    /// `seed`, the same sequence on every target): what the firmware's
    /// on-target check evaluates and the host compares bit for bit.
    pub fn box_sample(&self, seed: &mut u32) -> [i16; P] {
        let mut q = [0i16; P];
        for (qj, &(_, lb, ub)) in q.iter_mut().zip(&self.params) {
            *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let span = (i32::from(ub) - i32::from(lb)) as u32 + 1; // new: lb <= ub
            let r = ((*seed >> 16) * span) >> 16; // < span
            *qj = (i32::from(lb) + r as i32) as i16;
        }
        q
    }

    /// The whole law's parameter of the on-target check's sample `i` as
    /// Q15.16 bits (test instrumentation, the same on every target):
    /// `q` (from [`Self::box_sample`]) scaled back, for odd `i` moved off
    /// the quantisation grid by up to a unit either way (the rounding),
    /// and for every fourth `i` one parameter moved beyond its box by
    /// 2^12 units (the projection).
    #[doc(hidden)]
    pub fn check_bits(&self, q: &[i16; P], i: u16) -> [i32; P] {
        let mut bits = [0i32; P];
        for (j, (b, (&qj, &(s, _, _)))) in
            bits.iter_mut().zip(q.iter().zip(&self.params)).enumerate()
        {
            // 2^s by multiplication (s <= 16): no variable shift.
            let unit = 2i32.pow(u32::from((s as u8).min(16)));
            *b = i32::from(qj) * unit;
            let h = u32::from(i)
                .wrapping_mul(9)
                .wrapping_add(j as u32)
                .wrapping_mul(2_654_435_761);
            if i % 2 == 1 {
                // An offset in [-2^s, 2^s).
                *b += ((h >> 8) as i32 & (2 * unit - 1)) - unit;
            }
            if i.is_multiple_of(4) && j == usize::from(i / 4) % P {
                let far = unit * 4096;
                *b += if h & 1 == 0 { far } else { -far };
            }
        }
        bits
    }

    /// The whole law's `f32` parameter of the on-target check's sample `i`
    /// (test instrumentation, the same on every target): the values of
    /// `bits` (from [`Self::check_bits`]) with up to the 8 low mantissa
    /// bits flipped (bits below Q15.16's resolution, where the rounding
    /// to Q15.16 happens; zero becomes a subnormal), and for every 16th
    /// `i` (`i % 16 == 5`) one value non-finite (a NaN or an infinity).
    #[doc(hidden)]
    pub fn check_f32(&self, bits: &[i32; P], i: u16) -> [f32; P] {
        let mut v = [0f32; P];
        for (j, (vj, &b)) in v.iter_mut().zip(bits).enumerate() {
            let h = u32::from(i)
                .wrapping_mul(9)
                .wrapping_add(j as u32)
                .wrapping_mul(2_246_822_519);
            let f = <f32 as RtScalar>::from_q16(b);
            let mut v = f.to_bits() ^ ((h >> 20) & 0xFF);
            if i % 16 == 5 && j == usize::from(i / 16) % P {
                // The exponent all ones: an infinity (mantissa 0) or a
                // NaN, either sign.
                v = (v & 0x8000_0000) | 0x7F80_0000 | (h & 0x40_0000);
            }
            *vj = f32::from_bits(v);
        }
        v
    }

    /// Rows evaluated in the current period (test instrumentation).
    #[doc(hidden)]
    pub fn rows_evaluated(&self) -> usize {
        self.scratch
            .cache
            .iter()
            .filter(|e| e[0] == self.period)
            .count()
    }
}
