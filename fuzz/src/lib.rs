//! The fuzz entry points (`harness.rs`, shared with the regression test
//! `tests/tests/fuzz_regressions.rs`) and the allocation limit of the fuzz
//! runs.
//!
//! A reader's memory must follow the size of its input: under fuzzing, one
//! allocation above [`ALLOC_LIMIT`] bytes aborts the run (a crash libFuzzer
//! records), so a short file that claims a huge matrix is caught.

mod harness;
pub use harness::*;

use std::alloc::{GlobalAlloc, Layout, System};

/// The largest single allocation a fuzz input may cause (32 MiB; the
/// inputs are at most a few tens of kilobytes).
pub const ALLOC_LIMIT: usize = 32 << 20;

/// The system allocator with [`ALLOC_LIMIT`] on every allocation.
struct Limited;

// SAFETY: forwards to the system allocator; refusing an allocation
// (a null pointer) is allowed and ends in `handle_alloc_error`.
unsafe impl GlobalAlloc for Limited {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: Limited = Limited;
