//! Helpers of the GPU tests: the device (or a skip, or a failure when
//! `POROSPH_REQUIRE_GPU=1`), and random particle sets.
#![allow(dead_code)]

use porosph::backend::gpu::{GpuBackend, GpuContext};
use porosph::backend::GpuPasses;

/// Whether CI demands a GPU adapter (lavapipe there): then a missing one
/// fails the test instead of skipping it.
pub fn required() -> bool {
    std::env::var("POROSPH_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

fn missing(e: impl std::fmt::Display) {
    if required() {
        panic!("POROSPH_REQUIRE_GPU=1 but {e}");
    }
    eprintln!("skipped: {e}");
}

/// The GPU device, or None (test skipped) where there is none.
pub fn context() -> Option<GpuContext> {
    GpuContext::new().map_err(missing).ok()
}

/// A GPU backend running `passes`, or None (test skipped).
pub fn backend(passes: GpuPasses) -> Option<GpuBackend> {
    GpuBackend::new(passes).map_err(missing).ok()
}

/// xorshift64*: a fixed, dependency-free random sequence.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next_u64() >> 40) as f32 / (1u64 << 24) as f32)
    }
}
