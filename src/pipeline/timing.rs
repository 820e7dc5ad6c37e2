//! Names and timers of the passes of a step (PHYSICS.md §6). The same names
//! head the `ms_<pass>` columns of `stats.csv` on every backend.

use std::time::Instant;

/// The passes of a step, in order, with their PHYSICS.md §6 numbers:
/// 0 neighbour search (incl. Morton sort and reorder), 1 phase bookkeeping,
/// 2 densities and volumes (4a-b), 3 viscosity and u*, 4c sources and
/// diagonal, 5 the IISPH Jacobi loop, 6 and 8 the elastic solids
/// (deformation, stress, conjugate gradients; 0 ms without solids),
/// 6-7 and 9 the porous coupling (absorbed volume, pore pressure, Darcy
/// flux, the fluid's porous terms and accelerations; 0 ms without porous
/// solids), 10 drift velocities, 11 the drift
/// momentum term, 12 volume-fraction transport, 13 integration, 14 the
/// volume-fraction correction and 14 the next time step (CFL). Passes 10,
/// 11, 12 and the correction run only with two or more phases (0 ms else).
pub const PASSES: [&str; 14] = [
    "neighbors",
    "phases",
    "densities",
    "viscosity",
    "ppe_setup",
    "pressure_solve",
    "elasticity",
    "porous",
    "drift",
    "drift_momentum",
    "phase_transport",
    "integrate",
    "phase_correction",
    "time_step",
];

/// Index of each pass in [`PASSES`].
pub mod pass {
    pub const NEIGHBORS: usize = 0;
    pub const PHASES: usize = 1;
    pub const DENSITIES: usize = 2;
    pub const VISCOSITY: usize = 3;
    pub const PPE_SETUP: usize = 4;
    pub const PRESSURE_SOLVE: usize = 5;
    pub const ELASTICITY: usize = 6;
    pub const POROUS: usize = 7;
    pub const DRIFT: usize = 8;
    pub const DRIFT_MOMENTUM: usize = 9;
    pub const PHASE_TRANSPORT: usize = 10;
    pub const INTEGRATE: usize = 11;
    pub const PHASE_CORRECTION: usize = 12;
    pub const TIME_STEP: usize = 13;
}

/// Wall-clock milliseconds per pass of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassTimes {
    pub ms: [f64; PASSES.len()],
    /// Device milliseconds (timestamp queries) of the passes that ran on
    /// the GPU; 0 for a pass on the CPU (`stats.csv`: `gpu_ms_<pass>`).
    pub gpu_ms: [f64; PASSES.len()],
}

impl PassTimes {
    /// Runs `f`, adding its wall time to pass `p`.
    #[inline]
    pub fn time<T>(&mut self, p: usize, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let r = f();
        self.ms[p] += t.elapsed().as_secs_f64() * 1e3;
        r
    }

    /// Sum over passes, ms.
    pub fn total(&self) -> f64 {
        self.ms.iter().sum()
    }
}
