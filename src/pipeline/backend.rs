//! Which backend computes the offloaded passes of a [`Simulation`].

use super::Simulation;
use crate::backend::gpu::GpuBackend;
use crate::backend::BackendKind;

impl Simulation {
    /// From the next step on, runs the passes `gpu.passes` selects on the
    /// GPU (`--backend gpu`); the other passes stay on the CPU.
    pub fn use_gpu(&mut self, gpu: GpuBackend) {
        self.backend = Box::new(gpu);
    }

    /// The backend the simulation runs on.
    pub fn backend(&self) -> BackendKind {
        self.backend.kind()
    }

    /// The GPU backend, if any.
    pub fn gpu(&self) -> Option<&GpuBackend> {
        self.backend.as_any().downcast_ref::<GpuBackend>()
    }
}
