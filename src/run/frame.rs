//! Assembling a [`Frame`] (every particle as one point set) from the stores.

use crate::io::{ArrayData, Frame, PointArray};
use crate::pipeline::Simulation;

/// `kind` values in frames.
pub mod kind {
    pub const FLUID: u8 = 0;
    pub const SOLID: u8 = 1;
    pub const WALL: u8 = 2;
}

fn array(name: &str, unit: &str, components: usize, data: ArrayData) -> PointArray {
    PointArray { name: name.to_string(), unit: unit.to_string(), components, data }
}

impl Simulation {
    /// The current state as a frame: fluid particles first, then walls.
    pub fn frame(&self) -> Frame {
        let (f, w) = (&self.fluid, &self.walls);
        let (nf, nw) = (f.len(), w.len());
        let mut points = Vec::with_capacity(nf + nw);
        points.extend((0..nf).map(|i| [f.x[i], f.y[i], f.z[i]]));
        points.extend((0..nw).map(|i| [w.x[i], w.y[i], w.z[i]]));
        let mut velocity = Vec::with_capacity(3 * (nf + nw));
        for i in 0..nf {
            velocity.extend([f.ux[i], f.uy[i], f.uz[i]]);
        }
        velocity.resize(3 * (nf + nw), 0.0);
        let cat = |a: &[f32], b: &[f32]| -> Vec<f32> { a.iter().chain(b).copied().collect() };
        let mut kinds = vec![kind::FLUID; nf];
        kinds.resize(nf + nw, kind::WALL);
        let k = f.alpha.len();
        let mut alpha = Vec::with_capacity(k * (nf + nw));
        for i in 0..nf {
            alpha.extend(f.alpha.iter().map(|a| a[i]));
        }
        alpha.resize(k * (nf + nw), 0.0);
        let mut color = Vec::with_capacity(3 * (nf + nw));
        for i in 0..nf {
            let mut c = [0.0f32; 3];
            for (ph, a) in self.scene.phases.iter().zip(&f.alpha) {
                for (cc, pc) in c.iter_mut().zip(ph.color) {
                    *cc += a[i] * pc;
                }
            }
            color.extend(c);
        }
        for _ in 0..nw {
            color.extend([0.6, 0.6, 0.6]);
        }
        Frame {
            time: self.time,
            step: self.step,
            points,
            arrays: vec![
                array("velocity", "m/s", 3, ArrayData::F32(velocity)),
                array("pressure", "Pa", 1, ArrayData::F32(cat(&f.pressure, &w.pressure))),
                array("density", "kg/m^3", 1, ArrayData::F32(cat(&f.density, &w.density))),
                array("alpha", "", k, ArrayData::F32(alpha)),
                array("color", "", 3, ArrayData::F32(color)),
                array("kind", "", 1, ArrayData::U8(kinds)),
                array("id", "", 1, ArrayData::U32(f.id.iter().chain(&w.id).copied().collect())),
            ],
        }
    }
}
