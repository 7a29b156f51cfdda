//! Outgoing QUIC datagrams cost no heap allocation once the stream is steady. The datagrams
//! are cut on this test's thread, so a per-thread allocation count sees every one.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::collections::VecDeque;

use haptics_client::quic::DatagramArena;

struct Counting;

thread_local! {
    // Per thread: the test harness's own threads allocate while the test runs (its main
    // thread waiting on the test's result), and a process-wide count would see them.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
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
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_steady_datagram_stream_allocates_nothing_after_warm_up() {
    let mut arena = DatagramArena::new();
    // Up to 16 datagrams queued in the transport at a time, sent in order.
    let mut queued: VecDeque<bytes::Bytes> = VecDeque::with_capacity(16);
    let packet = [0xA5u8; 118];
    let send = |arena: &mut DatagramArena, queued: &mut VecDeque<bytes::Bytes>, i: usize| {
        if queued.len() == 16 {
            queued.pop_front();
        }
        let mut p = packet;
        p[0] = i as u8;
        let b = arena.bytes(&p);
        assert_eq!(b.len(), 118);
        assert_eq!(b[0], i as u8);
        queued.push_back(b);
    };
    for i in 0..2_000 {
        send(&mut arena, &mut queued, i);
    }
    let before = ALLOCATIONS.with(Cell::get);
    // 20 s at 1 kHz.
    for i in 0..20_000 {
        send(&mut arena, &mut queued, i);
    }
    let during = ALLOCATIONS.with(Cell::get) - before;
    // ~36 blocks' worth, each taken back in place (a copy per datagram would be 20,000).
    assert_eq!(during, 0, "allocations for 20,000 datagrams");
}
