//! Memory that lives for one pass. The step arena keeps what later stages
//! read until the step ends, and a bump allocator frees nothing before its
//! reset, so a pass's own temporaries there (sums, limits, copies its
//! kernels work in) stay resident through the rest of the step and add up
//! over the stages: in the porous three-phase bench the arena's
//! high-water mark was 774 B per fluid particle, of which the drift's, the
//! transport's and the pore terms' temporaries were about a third. A pass
//! takes its temporaries from [`PassScratch::fresh`], which hands back the
//! last pass's: the step's peak is then its lasting outputs plus the
//! largest pass's temporaries, not their sum.

use bumpalo::Bump;

/// Scratch of one pass at a time (reset by the next [`PassScratch::fresh`]).
#[derive(Default)]
pub(super) struct PassScratch {
    bump: Bump,
    /// The most bytes one pass has used (the high-water mark).
    used: usize,
}

impl PassScratch {
    /// Empty scratch for the next pass; what the last pass took is freed
    /// (the borrow checker keeps it from outliving this call's borrow).
    pub fn fresh(&mut self) -> &Bump {
        self.note_used();
        self.bump.reset();
        &self.bump
    }

    /// Records the current pass's use in the high-water mark.
    pub fn note_used(&mut self) {
        self.used = self.used.max(self.bump.allocated_bytes() - self.bump.chunk_capacity());
    }

    /// The most bytes one pass has used so far.
    pub fn used(&self) -> usize {
        self.used
    }

    /// Bytes held (the chunks' capacity).
    pub fn bytes(&self) -> usize {
        self.bump.allocated_bytes()
    }
}
