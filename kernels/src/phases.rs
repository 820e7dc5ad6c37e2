//! Per-phase data of the mixture passes (PHYSICS.md §4.1): phase constants,
//! per-phase velocity fields, and the fraction guards shared by the passes.
//!
//! A per-phase field is one slice per phase k (`&[&[f32]]`, index `[k][i]`),
//! so the store's `alpha` (and later `beta`) and arena scratch both pass as
//! explicit slices, the way a GPU pass binds one buffer per array.

/// Below this outer fraction alpha_f a particle has no drift (u_mk = 0) and
/// takes no part in the pressure solve (PHYSICS.md §2.4, §4.1).
pub use crate::iisph::MIN_ALPHA_F;

/// Below this normalised fraction alpha_k / alpha_f the diffusion term
/// sigma grad(alpha_k) / alpha_k of phase k is dropped (PHYSICS.md §4.1).
pub const MIN_PHASE_FRACTION: f32 = 0.01;

/// Constants of one phase k used by the drift passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseConstants {
    /// Rest density rho_k, kg/m^3.
    pub density: f32,
    /// Drift relaxation weight tau_k, m^2/(Pa s) = m^3 s/kg (P-Eq. 11;
    /// units per PHYSICS.md §7).
    pub tau: f32,
    /// Drift diffusion weight sigma_k, m^2/s (P-Eq. 11).
    pub sigma: f32,
}

/// A vector field per phase: `x[k][i]`, `y[k][i]`, `z[k][i]`.
#[derive(Clone, Copy)]
pub struct PhaseVel<'a> {
    pub x: &'a [&'a [f32]],
    pub y: &'a [&'a [f32]],
    pub z: &'a [&'a [f32]],
}

impl<'a> PhaseVel<'a> {
    /// Number of phases.
    pub fn phases(&self) -> usize {
        self.x.len()
    }

    /// The field of phase `k`.
    pub fn phase(&self, k: usize) -> crate::iisph::Vel<'a> {
        crate::iisph::Vel { x: self.x[k], y: self.y[k], z: self.z[k] }
    }
}

/// Three output slices of a vector field (one pass writes them together).
pub use crate::iisph::VelMut;
