//! [`KestrelStatus`]: the return code of every function, and the
//! exhaustive mapping from the run-time's [`Error`].

use kestrel_core::Error;

/// What a function returns: `KESTREL_STATUS_OK` or why it did nothing
/// useful. No function panics or aborts; on an error the outputs are left
/// as they were unless the function says otherwise.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KestrelStatus {
    /// Success.
    Ok = 0,
    /// A required pointer was NULL (or a table had neither RAM bytes nor
    /// a flash address).
    NullPointer = 1,
    /// A table's length, a layout's counts or a dimension do not match
    /// what the function serves (kestrel_core `DimensionMismatch`).
    BadSize = 2,
    /// A table set's checksum differs from the CRC of its bytes.
    BadChecksum = 3,
    /// A table's number format is not the function's (f32 tables given
    /// to a Q15.16 function or the other way round), or unknown.
    BadFormat = 4,
    /// The state was not initialised by its `_init` function (or its
    /// init failed).
    NotInitialised = 5,
    /// An input or a table holds NaN or an infinity, or a fixed-point
    /// value overflowed (kestrel_core `NonFinite`).
    NonFinite = 6,
    /// The constraints admit no solution, e.g. an empty input box
    /// (kestrel_core `Infeasible`).
    Infeasible = 7,
    /// A table value is outside its documented range, e.g. a row shift
    /// above 40 or a parameter box with lb > ub (kestrel_core
    /// `InvalidArgument`).
    InvalidTable = 8,
    /// A table index points outside the table (kestrel_core `OutOfRange`).
    OutOfRange = 9,
    /// A matrix that must be invertible is singular (kestrel_core
    /// `Singular`; not returned by the present functions).
    Singular = 10,
    /// A matrix that must be positive definite is not (kestrel_core
    /// `NotPositiveDefinite`; not returned by the present functions).
    NotPositiveDefinite = 11,
    /// The problem has no finite optimum (kestrel_core `Unbounded`; not
    /// returned by the present functions).
    Unbounded = 12,
    /// An iterative method stopped before its tolerance (kestrel_core
    /// `NotConverged`; not returned by the present functions).
    NotConverged = 13,
    /// An error of the run-time that has no code of its own here
    /// (kestrel_core's `Error` is `#[non_exhaustive]`; every variant it
    /// has today is mapped above).
    Other = 14,
}

/// The status of a run-time error: one code per `Error` variant.
pub fn status_of(e: Error) -> KestrelStatus {
    match e {
        Error::DimensionMismatch { .. } => KestrelStatus::BadSize,
        Error::NonFinite => KestrelStatus::NonFinite,
        Error::Singular => KestrelStatus::Singular,
        Error::NotPositiveDefinite => KestrelStatus::NotPositiveDefinite,
        Error::Infeasible => KestrelStatus::Infeasible,
        Error::Unbounded => KestrelStatus::Unbounded,
        Error::NotConverged => KestrelStatus::NotConverged,
        Error::InvalidArgument(_) => KestrelStatus::InvalidTable,
        Error::OutOfRange => KestrelStatus::OutOfRange,
        // A variant added to kestrel_core after this mapping: not renamed
        // to one of the codes above.
        _ => KestrelStatus::Other,
    }
}

impl From<Error> for KestrelStatus {
    fn from(e: Error) -> Self {
        status_of(e)
    }
}

/// `Ok` for `Ok(())`, the error's code otherwise.
pub(crate) fn code(r: Result<(), KestrelStatus>) -> KestrelStatus {
    match r {
        Ok(()) => KestrelStatus::Ok,
        Err(e) => e,
    }
}
