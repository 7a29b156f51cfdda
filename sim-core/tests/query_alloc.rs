//! `value_and_gradient` and `project_to_zero_set` must not allocate: they run per haptic tick
//! and per grid node. A counting global allocator proves it for queries near and far from the
//! surface, including the nearest-point fallback.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use glam::DVec3;
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, reconstruct};
use sim_core::sampling::Shape;
use sim_core::{FitParams, NoProgress};

struct Counting;

thread_local! {
    // Per thread: the queries run on this test's thread, while the fit's worker threads and the
    // test harness's own threads may still allocate during the measured loop.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: the slot may be gone while a thread is being torn down.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: forwards to the system allocator with the caller's arguments unchanged; the counter
// is a const-initialised thread-local `Cell` that never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn queries_do_not_allocate() {
    let shape = Shape::Torus {
        major: 1.0,
        minor: 0.4,
    };
    let rec = reconstruct(
        &shape.sample(5000, 1),
        &FitParams::default(),
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )
    .expect("fit");
    let probes: Vec<DVec3> = shape
        .sample(500, 2)
        .positions
        .iter()
        .flat_map(|p| [*p * 1.01, *p * 0.99, *p * 3.0, DVec3::ZERO])
        .collect();
    let before = ALLOCATIONS.with(Cell::get);
    let mut sum = 0.0;
    for &x in &probes {
        let (f, g) = rec.field.value_and_gradient(x);
        sum += f + g.x + rec.field.project_to_zero_set(x).point.y;
    }
    let after = ALLOCATIONS.with(Cell::get);
    assert!(sum.is_finite());
    assert_eq!(
        after - before,
        0,
        "{} allocations in {} queries",
        after - before,
        probes.len()
    );
}
