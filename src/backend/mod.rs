//! Backends: who computes a pass. The step asks a [`Passes`] (the pass
//! interface, [`passes`]) for the passes a backend may run (PHYSICS.md §6:
//! the neighbour sort, the IISPH Jacobi loop, the drift velocities): the
//! CPU backend ([`cpu`]) runs them with the `porosph-kernels` passes, the
//! GPU backend ([`gpu`]) through wgpu; every other pass is the CPU's. A run
//! picks `--backend cpu|gpu` and, for studies, which passes go to the GPU
//! (`--gpu-passes`).

pub mod cpu;
pub mod gpu;
pub mod passes;

pub use cpu::Cpu;
pub use passes::{Pass, Passes};

use std::fmt;
use std::str::FromStr;

/// Where a run computes its passes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BackendKind {
    /// Every pass on the CPU (bitwise deterministic, exact restart).
    #[default]
    Cpu,
    /// The passes of a [`GpuPasses`] set on the GPU, the rest on the CPU.
    Gpu,
}

impl FromStr for BackendKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cpu" => Ok(Self::Cpu),
            "gpu" => Ok(Self::Gpu),
            _ => Err(format!("unknown backend `{s}`: expected `cpu` or `gpu`")),
        }
    }
}

impl fmt::Display for BackendKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Cpu => "cpu",
            Self::Gpu => "gpu",
        })
    }
}

/// Which passes go to the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpuPasses {
    /// Pass 0, neighbour search: its Morton keys and sort, and the
    /// cell-range tables the step's GPU passes read (the cell grid and the
    /// pairs the CPU passes read are built on the CPU).
    pub neighbors: bool,
    /// Pass 5, the IISPH relaxed Jacobi loop.
    pub pressure_solve: bool,
    /// Pass 10, the drift velocities of the mixture model (two or more
    /// phases; the maximum drift speed is taken on the CPU).
    pub drift: bool,
}

impl GpuPasses {
    /// Every pass the GPU backend implements.
    pub const ALL: GpuPasses = GpuPasses { neighbors: true, pressure_solve: true, drift: true };

    /// The passes the GPU backend can run, in the order of the step.
    pub const PASSES: [Pass; 3] = [Pass::Neighbors, Pass::PressureSolve, Pass::Drift];

    /// Whether pass `p` goes to the GPU.
    pub fn contains(&self, p: Pass) -> bool {
        match p {
            Pass::Neighbors => self.neighbors,
            Pass::PressureSolve => self.pressure_solve,
            Pass::Drift => self.drift,
            _ => false,
        }
    }
}

impl Default for GpuPasses {
    fn default() -> Self {
        Self::ALL
    }
}

impl FromStr for GpuPasses {
    type Err = String;
    /// A comma-separated list of pass names (`neighbors`, `pressure_solve`, `drift`), or `all`.
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "all" {
            return Ok(Self::ALL);
        }
        let mut set = GpuPasses { neighbors: false, pressure_solve: false, drift: false };
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match Pass::from_name(name) {
                Some(Pass::Neighbors) => set.neighbors = true,
                Some(Pass::PressureSolve) => set.pressure_solve = true,
                Some(Pass::Drift) => set.drift = true,
                _ => {
                    let names: Vec<&str> = Self::PASSES.iter().map(|p| p.name()).collect();
                    return Err(format!(
                        "`{name}` is not a pass the GPU backend runs: expected a comma-separated list of {} or `all`",
                        names.join(", ")
                    ));
                }
            }
        }
        Ok(set)
    }
}
