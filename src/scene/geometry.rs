//! Sampling shapes into particles on the lattice of spacing d. (placeholder: being written)
use super::Scene;

/// Fluid particles sampled from all `[[fluid]]` blocks.
#[derive(Clone, Debug, Default)]
pub struct SampledFluid {
    /// Positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Velocities, m/s.
    pub velocities: Vec<[f32; 3]>,
    /// Per particle, the volume fraction of each phase (len = number of phases).
    pub fractions: Vec<Vec<f32>>,
}

/// Static wall particles sampled from all `[[wall]]` entries.
#[derive(Clone, Debug, Default)]
pub struct SampledWalls {
    /// Positions, m.
    pub positions: Vec<[f32; 3]>,
}

/// Samples the fluid blocks of a scene.
pub fn sample_fluid(_scene: &Scene, _walls: &SampledWalls) -> SampledFluid {
    unimplemented!("geometry")
}

/// Samples the walls of a scene.
pub fn sample_walls(_scene: &Scene) -> SampledWalls {
    unimplemented!("geometry")
}
