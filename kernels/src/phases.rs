//! Per-phase data of the mixture passes (PHYSICS.md §4.1): phase constants,
//! per-phase velocity fields, and the fraction guards shared by the passes.
//!
//! A per-phase field is one slice per phase k (`&[&[f32]]`, index `[k][i]`),
//! so the store's `alpha` (and later `beta`) and arena scratch both pass as
//! explicit slices, the way a GPU pass binds one buffer per array.

use crate::soa::Vel;
use bumpalo::Bump;

/// Below this outer fraction alpha_f a particle has no drift (u_mk = 0) and
/// takes no part in the pressure solve (PHYSICS.md §2.4, §4.1).
pub use crate::iisph::MIN_ALPHA_F;

/// Below this normalised fraction alpha_k / alpha_f the diffusion term
/// sigma grad(alpha_k) / alpha_k of phase k is dropped (PHYSICS.md §4.1).
pub const MIN_PHASE_FRACTION: f32 = 0.01;

/// A volume fraction as the store keeps it: `hi`, the f32 that every pass
/// reads, and `lo`, the part of the fraction that f32 cannot hold
/// (|lo| <= ulp(hi) / 2), so that hi + lo carries about 48 bits. The
/// passes that move fractions (transport, absorption exchange, the
/// correction, the moves in and out of solids) compute hi + lo + change in
/// f64 and store it split again. With f32 alone the phases' volumes drift:
/// a pure particle (alpha_k = 1) that loses less than half an ulp of 1
/// (3e-8) to a neighbour keeps 1 while the neighbour gains it, and since
/// diffusion always flows out of pure particles the rounding is biased
/// (measured in Example 6: +8.3e-7 of blue's volume in 0.3 s, from the
/// transport at alpha = 1 and the correction that renormalised it).
#[inline(always)]
pub fn join(hi: f32, lo: f32) -> f64 {
    f64::from(hi) + f64::from(lo)
}

/// Splits `v` into the `hi` and `lo` of [`join`]: hi is v rounded to f32,
/// lo the remainder (exact in f64, rounded to f32).
#[inline(always)]
pub fn split(v: f64) -> (f32, f32) {
    let hi = v as f32;
    (hi, (v - f64::from(hi)) as f32)
}

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
    /// Per-phase views of a field holding phase k at `[k n, (k + 1) n)`
    /// of each component (the slice lists from `arena`).
    pub fn split(arena: &'a Bump, v: Vel<'a>, n: usize) -> PhaseVel<'a> {
        PhaseVel {
            x: arena.alloc_slice_fill_iter(v.x.chunks(n.max(1))),
            y: arena.alloc_slice_fill_iter(v.y.chunks(n.max(1))),
            z: arena.alloc_slice_fill_iter(v.z.chunks(n.max(1))),
        }
    }

    /// Number of phases.
    pub fn phases(&self) -> usize {
        self.x.len()
    }

    /// The field of phase `k`.
    pub fn phase(&self, k: usize) -> Vel<'a> {
        Vel { x: self.x[k], y: self.y[k], z: self.z[k] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_keeps_what_f32_rounds_away() {
        // 1 - 1e-8 is 1 in f32; hi + lo holds it.
        let v = 1.0 - 1e-8;
        let (hi, lo) = split(v);
        assert_eq!(hi, 1.0);
        assert!((join(hi, lo) - v).abs() < 1e-15, "{}", join(hi, lo) - v);
        // Ten thousand losses of 1e-9 from a pure particle: f32 alone keeps 1.
        let (mut hi, mut lo, mut plain) = (1.0f32, 0.0f32, 1.0f32);
        for _ in 0..10_000 {
            (hi, lo) = split(join(hi, lo) - 1e-9);
            plain -= 1e-9;
        }
        assert_eq!(plain, 1.0);
        assert!((join(hi, lo) - (1.0 - 1e-5)).abs() < 1e-12, "{}", join(hi, lo));
    }
}
