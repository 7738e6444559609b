//! The small, `Copy` error type shared by the run-time (no_std) code.

use core::fmt;

/// Errors of the run-time code: small, `Copy`, allocation-free.
///
/// Design-time crates wrap this in their own `thiserror` enums; run-time
/// code (Kalman step, tree walk, fast-gradient iterations) returns it as is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Error {
    /// A slice or matrix had the wrong length or shape.
    DimensionMismatch {
        /// The length the callee needs.
        expected: usize,
        /// The length it was given.
        found: usize,
    },
    /// An input contained NaN or an infinity.
    NonFinite,
    /// A matrix that must be invertible is (numerically) singular.
    Singular,
    /// A matrix that must be positive (semi)definite is not.
    NotPositiveDefinite,
    /// The constraints admit no solution.
    Infeasible,
    /// The problem has no finite optimum, or a set that must be bounded is not.
    Unbounded,
    /// An iterative method stopped before meeting its tolerance.
    NotConverged,
    /// A parameter is outside its documented range; the text names it.
    InvalidArgument(&'static str),
    /// A value lies outside the region or table it was looked up in.
    OutOfRange,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::DimensionMismatch { expected, found } => {
                write!(f, "dimension mismatch: expected {expected}, found {found}")
            }
            Error::NonFinite => f.write_str("non-finite value (NaN or infinity)"),
            Error::Singular => f.write_str("matrix is singular"),
            Error::NotPositiveDefinite => f.write_str("matrix is not positive definite"),
            Error::Infeasible => f.write_str("problem is infeasible"),
            Error::Unbounded => f.write_str("problem or set is unbounded"),
            Error::NotConverged => f.write_str("iteration did not converge"),
            Error::InvalidArgument(what) => write!(f, "invalid argument: {what}"),
            Error::OutOfRange => f.write_str("value out of range"),
        }
    }
}

impl core::error::Error for Error {}

/// Checks that a slice has the expected length.
///
/// ```
/// use kestrel_core::{check_len, Error};
/// assert_eq!(check_len(&[1.0, 2.0], 2), Ok(()));
/// assert_eq!(check_len(&[1.0], 2), Err(Error::DimensionMismatch { expected: 2, found: 1 }));
/// ```
#[inline]
pub fn check_len<T>(slice: &[T], expected: usize) -> Result<(), Error> {
    if slice.len() == expected {
        Ok(())
    } else {
        Err(Error::DimensionMismatch {
            expected,
            found: slice.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_the_problem() {
        extern crate std;
        use std::string::ToString;
        let e = Error::DimensionMismatch {
            expected: 3,
            found: 2,
        };
        assert_eq!(e.to_string(), "dimension mismatch: expected 3, found 2");
        assert!(
            Error::InvalidArgument("horizon")
                .to_string()
                .contains("horizon")
        );
    }
}
