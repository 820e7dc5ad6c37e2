//! CPU compute kernels of porosph: the SPH kernel, SIMD lanes, and one module
//! per pass of the step (PHYSICS.md §6). Every pass is a gather over cache
//! blocks ([`blocks::BLOCK`]) run under rayon, with neighbour loops in SIMD
//! lanes ([`lanes::F`]); results do not depend on the number of threads.

pub mod band;
pub mod blocks;
pub mod chebyshev;
pub mod drift;
pub mod drift_momentum;
pub mod drucker_prager;
pub mod elasticity;
pub mod granular;
pub mod grid;
pub mod hydrostatic;
pub mod iisph;
pub mod integrate;
pub mod kernel;
pub mod lanes;
pub mod neighbors;
pub mod phase_transport;
pub mod phases;
pub mod porous;
pub mod rest_lattice;
pub mod rigid_modes;
pub mod soa;
pub mod solid_rows;
pub mod viscosity;
