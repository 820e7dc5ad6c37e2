//! porosph: several fluids flowing through and around porous, deformable
//! solids with one particle system (Ren, Xu, Li 2021).

pub mod io;
pub mod scene;
