//! The [`Q16Mac`] type: Q15.16 bits with the arithmetic of `kestrel_core::Q16`
//! (the operations are in the sibling modules: `arith` for the operators,
//! `Scalar` and `RtScalar`, `mul_wide` and `dot_wide` for the products).

use kestrel_core::Q16;

/// Q15.16 saturating fixed point with a 16-bit-multiply MAC (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(transparent)]
pub struct Q16Mac(pub i32);

impl Q16Mac {
    /// From the raw Q15.16 bits.
    #[inline]
    pub const fn from_bits(raw: i32) -> Self {
        Q16Mac(raw)
    }
    /// The raw Q15.16 bits.
    #[inline]
    pub const fn to_bits(self) -> i32 {
        self.0
    }
}

impl From<Q16> for Q16Mac {
    fn from(q: Q16) -> Self {
        Q16Mac(q.to_bits())
    }
}
