//! Timers of the passes of a step ([`Pass`], PHYSICS.md §6). The passes'
//! names head the `ms_<pass>` columns of `stats.csv` on every backend.

pub use crate::backend::passes::Pass;
use std::time::Instant;

/// Wall-clock milliseconds per pass of one step, indexed by
/// [`Pass::index`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassTimes {
    pub ms: [f64; Pass::COUNT],
    /// Device milliseconds (timestamp queries) of the passes that ran on
    /// the GPU; 0 for a pass on the CPU (`stats.csv`: `gpu_ms_<pass>`).
    pub gpu_ms: [f64; Pass::COUNT],
}

impl PassTimes {
    /// Runs `f`, adding its wall time to pass `p`.
    #[inline]
    pub fn time<T>(&mut self, p: Pass, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let r = f();
        self.add(p, t.elapsed().as_secs_f64() * 1e3);
        r
    }

    /// Adds `ms` milliseconds of wall time to pass `p`.
    #[inline]
    pub fn add(&mut self, p: Pass, ms: f64) {
        self.ms[p.index()] += ms;
    }

    /// Wall time of pass `p`, ms.
    pub fn ms(&self, p: Pass) -> f64 {
        self.ms[p.index()]
    }

    /// Device time of pass `p`, ms (0 for a pass on the CPU).
    pub fn gpu(&self, p: Pass) -> f64 {
        self.gpu_ms[p.index()]
    }

    /// Sets the device time of pass `p`, ms.
    pub fn set_gpu(&mut self, p: Pass, ms: f64) {
        self.gpu_ms[p.index()] = ms;
    }

    /// Sum over passes, ms.
    pub fn total(&self) -> f64 {
        self.ms.iter().sum()
    }
}
