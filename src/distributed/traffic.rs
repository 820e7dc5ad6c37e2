//! The halo bytes of one step: a model, field by field.
//!
//! A rank needs, for each halo particle, every value a pass reads from a
//! neighbour that was computed earlier in the same step (values of the
//! step before travel with the migration, and static ones once at setup).
//! [`FIELDS`] lists them from the passes of `pipeline::step::step_passes`,
//! each with the pass that reads it; [`HaloModel`] adds them up for a
//! scene's phases and solids, and [`HaloModel::bytes`] multiplies by the
//! halo counts of a [`super::Partition`].
//!
//! Not in the model: the elastic CG's vectors inside the solids'
//! compliance solve (their count per sweep depends on the body), the
//! granular sub-steps, the porous passes' solid-side fields beyond those
//! listed, message headers, and the migration (particles that change rank).
//! The distributed run will measure what it sends (`stats.csv`,
//! `halo_particles`); this is the dry run's estimate.

use super::partition::Kind;

/// How often a field is exchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Per {
    /// Once per step.
    Step,
    /// Once per step and phase (with two or more phases only).
    Phase,
    /// Once per Jacobi sweep of the pressure solve.
    Sweep,
}

/// When a field is needed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    Always,
    /// With two or more phases (the mixture passes).
    Mixture,
    /// With porous solids (the inner fractions).
    Porous,
}

/// A value a pass reads from a halo particle in the step it is computed.
#[derive(Clone, Copy, Debug)]
pub struct Field {
    pub kind: Kind,
    pub name: &'static str,
    pub bytes: u64,
    pub per: Per,
    pub when: When,
    /// The pass that reads it from the neighbour.
    pub read_by: &'static str,
}

const fn f(kind: Kind, name: &'static str, bytes: u64, per: Per, when: When, read_by: &'static str) -> Field {
    Field { kind, name, bytes, per, when, read_by }
}

use Kind::{Fluid, Solid, Wall};
use Per::{Phase, Step, Sweep};
use When::{Always, Mixture, Porous};

/// Every field of the model. Walls never move: their positions and rest
/// volumes are exchanged once, at setup, not per step.
pub const FIELDS: &[Field] = &[
    f(Fluid, "x (position)", 12, Step, Always, "pass 0: the pairs with the halo"),
    f(Fluid, "V0 (rest volume, alpha_f h^3)", 4, Step, Always, "volumes: sigma_i = sum V0_j W_ij"),
    f(Fluid, "u (velocity)", 12, Step, Always, "prediction: a^visc (P-Eq. 23)"),
    f(Fluid, "mu (viscosity)", 4, Step, Always, "prediction: (mu_i + mu_j) of P-Eq. 23"),
    f(Fluid, "V (volume)", 4, Step, Always, "pressure setup: Vbar_ij"),
    f(Fluid, "V/m", 4, Step, Always, "pressure setup: the diagonal a_ii"),
    f(Fluid, "u* (predicted velocity)", 12, Step, Always, "pressure setup: div* (P-Eq. 25)"),
    f(Fluid, "p (pressure)", 4, Sweep, Always, "solve: a^p (P-Eq. 27)"),
    f(Fluid, "a^p (pressure acceleration)", 12, Sweep, Always, "solve: (Ap)_i of P-Eq. 28"),
    f(Fluid, "p after the last sweep", 4, Step, Always, "solve: the final a^p"),
    f(Fluid, "alpha_k (fraction)", 4, Phase, Mixture, "drift: grad alpha_k; transport"),
    f(Fluid, "p / alpha_f", 4, Step, Mixture, "drift: grad p_k (P-Eq. 11)"),
    f(Fluid, "w_k (drift flux)", 12, Phase, Mixture, "transport: the pair fluxes (P-Eq. 7)"),
    f(Fluid, "lambda_k (limiter)", 4, Phase, Mixture, "transport: the pair limits"),
    f(Fluid, "beta_k (inner fraction)", 4, Phase, Porous, "porous: inner transport"),
    f(Wall, "V (volume)", 4, Step, Always, "pressure setup: Vbar_ib"),
    f(Wall, "p (pressure)", 4, Sweep, Always, "solve: a^p (P-Eq. 27)"),
    f(Wall, "p after the last sweep", 4, Step, Always, "solve: the final a^p"),
    f(Solid, "x (position)", 12, Step, Always, "pass 0: the pairs with the halo"),
    f(Solid, "V (volume)", 4, Step, Always, "volumes and pressure setup: sigma, Vbar_is"),
    f(Solid, "u* (predicted velocity)", 12, Step, Always, "pressure setup: div* (P-Eq. 25)"),
    f(Solid, "p (pressure)", 4, Sweep, Always, "solve: a^p and the solid force"),
    f(Solid, "a^p (pressure acceleration)", 12, Sweep, Always, "solve: (Ap)_i of P-Eq. 28"),
    f(Solid, "p after the last sweep", 4, Step, Always, "solve: the final a^p"),
];

/// Bytes per halo particle of each kind ([`Kind`] order) for one scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HaloModel {
    /// Exchanged once per step (the per-phase fields times the phases).
    pub per_step: [u64; 3],
    /// Exchanged once per Jacobi sweep.
    pub per_sweep: [u64; 3],
}

impl HaloModel {
    /// The model for a scene of `phases` phases, with or without porous
    /// solids.
    pub fn new(phases: usize, porous: bool) -> Self {
        let mut m = HaloModel { per_step: [0; 3], per_sweep: [0; 3] };
        for fd in FIELDS {
            let on = match fd.when {
                Always => true,
                Mixture => phases >= 2,
                Porous => porous,
            };
            if !on {
                continue;
            }
            let k = fd.kind as usize;
            match fd.per {
                Step => m.per_step[k] += fd.bytes,
                Phase => m.per_step[k] += fd.bytes * phases as u64,
                Sweep => m.per_sweep[k] += fd.bytes,
            }
        }
        m
    }

    /// Bytes per particle of kind `k` in a step of `sweeps` Jacobi sweeps.
    pub fn per_particle(&self, k: Kind, sweeps: u32) -> u64 {
        self.per_step[k as usize] + u64::from(sweeps) * self.per_sweep[k as usize]
    }

    /// Bytes a rank receives in one step of `sweeps` sweeps for a halo of
    /// `halo` particles of each kind.
    pub fn bytes(&self, halo: [usize; 3], sweeps: u32) -> u64 {
        Kind::ALL.iter().map(|&k| halo[k as usize] as u64 * self.per_particle(k, sweeps)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_phase_without_porous_solids_counts_the_always_fields() {
        let m = HaloModel::new(1, false);
        // x 12, V0 4, u 12, mu 4, V 4, V/m 4, u* 12, final p 4.
        assert_eq!(m.per_step[Fluid as usize], 56);
        assert_eq!(m.per_sweep[Fluid as usize], 16);
        assert_eq!(m.per_sweep[Wall as usize], 4);
        assert_eq!(m.bytes([10, 0, 0], 5), 10 * (56 + 5 * 16));
        // Two phases: alpha 4 + w 12 + lambda 4 per phase, p/alpha_f 4.
        assert_eq!(HaloModel::new(2, false).per_step[Fluid as usize], 56 + 4 + 2 * 20);
    }
}
