//! The counting global allocator of sim-core's allocation tests (included with `#[path]`; a
//! test binary installs it with `#[global_allocator] static ALLOCATOR: Counting = Counting;`).
//!
//! It counts per thread: a test measures the calls it makes on its own thread, and neither
//! parallel tests nor the test harness's threads (its main thread, waiting on a result,
//! allocates) nor a fit's worker threads can land in the window it measures.
#![allow(dead_code)] // each binary uses the counters it needs

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
    static ALLOCATED_BYTES: Cell<usize> = const { Cell::new(0) };
}

/// Counts the current thread's allocations, then defers to the system allocator.
pub struct Counting;

fn count(fresh_bytes: usize) {
    // `try_with`: the slots may be gone while a thread is being torn down.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
    let _ = ALLOCATED_BYTES.try_with(|c| c.set(c.get() + fresh_bytes));
}

// SAFETY: every call is forwarded unchanged to `System`, which upholds the `GlobalAlloc`
// contract; the counters are const-initialised thread-local `Cell`s (no allocation, no reentry).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size());
        // SAFETY: same contract as the caller's; `layout` is passed through.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count(layout.size());
        // SAFETY: same contract as the caller's; `layout` is passed through.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(0);
        // SAFETY: `ptr`/`layout` come from `System` (see `alloc`); forwarded unchanged.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (see `alloc`).
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Allocations (and reallocations) this thread has made so far.
pub fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

/// Bytes of this thread's fresh allocations (growing a buffer, in place or moved, is not
/// counted: arrays that grow amortised are not charged for it).
pub fn allocated_bytes() -> usize {
    ALLOCATED_BYTES.with(Cell::get)
}

/// How many allocations `f` makes on this thread.
pub fn allocations_in(f: impl FnOnce()) -> usize {
    let before = allocations();
    f();
    allocations() - before
}
