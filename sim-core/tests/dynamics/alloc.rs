//! The stepping contract: after warm-up, integrator steps, rope forces and snapshot publication
//! allocate nothing (counted per thread by the test binary's global allocator).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use glam::DVec3;
use sim_core::dynamics::{Integrator, NodeParams, Stepper};
use sim_core::tools::{Profile, Rope};

use crate::common::{perturb, small_model};

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Counts allocations made by the current thread, then defers to the system allocator.
pub struct Counting;

// SAFETY: every call is forwarded unchanged to `System`, which upholds the `GlobalAlloc`
// contract; the counter is a const-initialised thread-local `Cell` (no allocation, no reentry).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as ours; `layout` is passed through.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (see `alloc`).
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: `ptr`/`layout` come from `System` (see `alloc`); forwarded unchanged.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

#[test]
fn steps_tools_and_publishing_allocate_nothing_after_warm_up() {
    let rope = Rope {
        path: vec![DVec3::new(0.0, 0.0, 0.3)],
        radius: 0.2,
        strength: 0.1,
        profile: Profile::Gaussian,
        sheet: Some(DVec3::Z),
    };
    for integrator in [
        Integrator::forward_euler(1e3),
        Integrator::SymplecticEuler,
        Integrator::backward_euler(),
    ] {
        let mut m = small_model(10, NodeParams::default());
        perturb(&mut m, 1e-3);
        let mut st = Stepper::new(integrator);
        // Warm-up: scratch sized, snapshot pool filled (one held, one free).
        st.step(&mut m, 1e-3).unwrap();
        let held = m.publish();
        drop(m.publish());
        let before = allocations();
        for _ in 0..50 {
            m.clear_forces();
            rope.apply(&mut m).unwrap();
            st.step(&mut m, 1e-3).unwrap();
            drop(m.publish());
        }
        assert_eq!(allocations() - before, 0, "{} allocated", integrator.name());
        drop(held);
    }
}
