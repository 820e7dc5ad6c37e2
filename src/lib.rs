//! porosph: several fluids flowing through and around porous, deformable
//! solids with one particle system (Ren, Xu, Li 2021).
//!
//! Data flow: [`scene`] (parsed, validated TOML) -> [`store`] (struct of
//! arrays, Morton-sorted) -> [`pipeline`] (one step = the passes of
//! PHYSICS.md §6, computed by `porosph-kernels`) -> [`io`] (frames, stats).

pub mod backend;
pub mod builtin;
pub mod distributed;
pub mod io;
pub mod pipeline;
pub mod plot;
pub mod render;
pub mod run;
pub mod scene;
pub mod store;
