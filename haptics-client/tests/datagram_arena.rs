//! Outgoing QUIC datagrams cost no heap allocation once the stream is steady.

use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};

use haptics_client::quic::DatagramArena;

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards to the system allocator, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
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
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    // 20 s at 1 kHz.
    for i in 0..20_000 {
        send(&mut arena, &mut queued, i);
    }
    let during = ALLOCATIONS.load(Ordering::Relaxed) - before;
    // ~36 blocks' worth, each taken back in place (a copy per datagram would be 20,000).
    assert_eq!(during, 0, "allocations for 20,000 datagrams");
}
