//! Caller-owned state: a Rust value kept in an opaque C struct of `u64`
//! words, behind a marker word that tells an initialised state from any
//! other bytes.

use crate::status::KestrelStatus;
use core::mem::{MaybeUninit, align_of, size_of};

/// The marker of an initialised state ("KSTR").
const MAGIC: u32 = 0x4B53_5452;

/// The layout inside an opaque state: the marker, then the value.
#[repr(C)]
struct Slot<T> {
    magic: u32,
    value: MaybeUninit<T>,
}

/// Whether `Slot<T>` fits in `O` (checked at compile time by `init`).
const fn fits<T, O>() -> bool {
    size_of::<Slot<T>>() <= size_of::<O>() && align_of::<Slot<T>>() <= align_of::<O>()
}

/// Writes `value` into the opaque state `out` and marks it initialised;
/// an error from `value` leaves it marked uninitialised.
///
/// # Safety
/// `out` is NULL or points at a writable `O`.
pub(crate) unsafe fn init<T, O>(
    out: *mut O,
    value: impl FnOnce() -> Result<T, KestrelStatus>,
) -> KestrelStatus {
    const { assert!(fits::<T, O>(), "the opaque state is too small") };
    if out.is_null() {
        return KestrelStatus::NullPointer;
    }
    let slot = out.cast::<Slot<T>>();
    // SAFETY: `out` is a writable `O`, which holds a `Slot<T>` (size and
    // alignment checked above); `magic` is a plain u32.
    unsafe { core::ptr::addr_of_mut!((*slot).magic).write(0) };
    match value() {
        Ok(v) => {
            // SAFETY: as above.
            unsafe {
                core::ptr::addr_of_mut!((*slot).value).write(MaybeUninit::new(v));
                core::ptr::addr_of_mut!((*slot).magic).write(MAGIC);
            }
            KestrelStatus::Ok
        }
        Err(e) => e,
    }
}

/// [`init`] with the value written in place by `value` into the state's
/// memory (no by-value return of a large value through the stack).
///
/// # Safety
/// As [`init`]; `value` must have written the whole value when it returns
/// `Ok`.
pub(crate) unsafe fn init_with<T, O>(
    out: *mut O,
    value: impl FnOnce(&mut MaybeUninit<T>) -> Result<(), KestrelStatus>,
) -> KestrelStatus {
    const { assert!(fits::<T, O>(), "the opaque state is too small") };
    if out.is_null() {
        return KestrelStatus::NullPointer;
    }
    let slot = out.cast::<Slot<T>>();
    // SAFETY: as in `init`.
    unsafe { core::ptr::addr_of_mut!((*slot).magic).write(0) };
    // SAFETY: the value field of the writable state, not otherwise
    // referenced.
    let dst = unsafe { &mut *core::ptr::addr_of_mut!((*slot).value) };
    match value(dst) {
        Ok(()) => {
            // SAFETY: as above; the value is written (the contract).
            unsafe { core::ptr::addr_of_mut!((*slot).magic).write(MAGIC) };
            KestrelStatus::Ok
        }
        Err(e) => e,
    }
}

/// The value in the opaque state `p`, if `init` put one there.
///
/// # Safety
/// `p` is NULL or points at an `O` that is either initialised by `init`
/// with a `T` or whose first four bytes are not the marker (zeroed
/// memory, or a state whose init failed), and no other reference to it
/// is live.
pub(crate) unsafe fn get<'a, T, O>(p: *mut O) -> Result<&'a mut T, KestrelStatus> {
    const { assert!(fits::<T, O>(), "the opaque state is too small") };
    if p.is_null() {
        return Err(KestrelStatus::NullPointer);
    }
    let slot = p.cast::<Slot<T>>();
    // SAFETY: `p` points at an `O` holding a `Slot<T>`; its first word is
    // read as bytes the caller wrote (or zeroed).
    let magic = unsafe { core::ptr::addr_of!((*slot).magic).read() };
    if magic != MAGIC {
        return Err(KestrelStatus::NotInitialised);
    }
    // SAFETY: the marker is written only after a value (the contract).
    Ok(unsafe { (*slot).value.assume_init_mut() })
}

/// The `N` values at `p` (a C array), or `KESTREL_STATUS_NULL_POINTER`.
///
/// # Safety
/// `p` is NULL or points at `N` readable values.
pub(crate) unsafe fn read_array<S: Copy, const N: usize>(
    p: *const S,
) -> Result<[S; N], KestrelStatus> {
    if p.is_null() {
        return Err(KestrelStatus::NullPointer);
    }
    // SAFETY: `N` readable values (the contract); any alignment.
    Ok(unsafe { p.cast::<[S; N]>().read_unaligned() })
}

/// Writes `v` to the C array `p` unless `p` is NULL (an optional output).
///
/// # Safety
/// `p` is NULL or points at `N` writable values.
pub(crate) unsafe fn write_array<S: Copy, const N: usize>(p: *mut S, v: &[S; N]) {
    if !p.is_null() {
        // SAFETY: `N` writable values (the contract); any alignment.
        unsafe { p.cast::<[S; N]>().write_unaligned(*v) };
    }
}
