//! "A step in steady state allocates nothing" (core issue): scratch comes
//! from the per-step arena and reused buffers. Checked with a counting
//! global allocator over steps of a settled tank.

mod common;

use porosph::pipeline::Simulation;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged, only counting calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn steady_state_steps_allocate_nothing() {
    common::with_threads(2, || {
        let mut sim = Simulation::new(common::scene_file("hydrostatic.toml"));
        // Let the buffers reach their working size.
        for _ in 0..100 {
            sim.step().unwrap_or_else(|e| panic!("{e}"));
        }
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        assert!(before > 0, "the counting allocator counts (setting up allocates)");
        for _ in 0..50 {
            sim.step().unwrap_or_else(|e| panic!("{e}"));
        }
        let n = ALLOCATIONS.load(Ordering::Relaxed) - before;
        println!("allocations in 50 steady-state steps: {n}");
        assert_eq!(n, 0);
    });
}
