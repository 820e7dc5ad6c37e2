//! Assembling a [`Frame`] (every particle as one point set) from the stores.

use crate::io::{ArrayData, Frame, PointArray};
use crate::pipeline::Simulation;
use crate::scene::SolidMaterial;

/// `kind` values in frames.
pub mod kind {
    pub const FLUID: u8 = 0;
    pub const SOLID: u8 = 1;
    pub const WALL: u8 = 2;
}

/// Display colour of dry solid particles (linear RGB).
const SOLID_COLOR: [f32; 3] = [0.80, 0.62, 0.38];
/// Display colour of a saturated porous solid (linear RGB); a solid's
/// colour goes from [`SOLID_COLOR`] to this with its saturation.
const WET_COLOR: [f32; 3] = [0.85, 0.33, 0.05];
/// Display colour of dry sand (granular solids, linear RGB).
const SAND_DRY_COLOR: [f32; 3] = [0.72, 0.55, 0.30];
/// Display colour of saturated sand (linear RGB): wet sand is darker; a
/// granular solid's colour goes from [`SAND_DRY_COLOR`] to this with its
/// saturation.
const SAND_WET_COLOR: [f32; 3] = [0.22, 0.14, 0.07];
/// Inner (absorbed) fluid is drawn in its phase colour times this, so outer
/// and inner phases can be told apart (the frame's `color`; `porosph render
/// --color saturation` divides it out again).
pub const INNER_SHADE: f32 = 0.45;

fn array(name: &str, unit: &str, components: usize, data: ArrayData) -> PointArray {
    PointArray { name: name.to_string(), unit: unit.to_string(), components, data }
}

impl Simulation {
    /// The current state as a frame: fluid particles first, then walls
    /// ([`Simulation::wall_rows`]), then solids. Solid particles carry
    /// `stress` (von Mises, Pa) and `strain_trace`, `saturation`,
    /// `pore_pressure` (Pa) and, granular ones, `plastic_strain`; those are
    /// 0 on fluid and walls. Fluid particles carry `alpha` and `beta` (outer
    /// and inner fractions, K components each in the scene's phase order, 0
    /// elsewhere) and the same per phase by name, `alpha_<phase>` and
    /// `beta_<phase>`. `density` (kg/m^3): of a fluid particle, the rest
    /// density of its outer (free) mixture times sigma = V0 / V, the volume
    /// ratio the pressure solve sees (below the rest density at a free
    /// surface, where the kernel support is partly empty); of a wholly
    /// absorbed particle, its inner mixture's rest density. Of a wall, the
    /// density of the fluid it stands in for (the pressure boundary's);
    /// of a solid, its body's density. Solids' `color` goes from dry to wet
    /// with the saturation, in sand colours for granular ones.
    pub fn frame(&self) -> Frame {
        let (f, w, s) = (&self.fluid, &self.walls, &self.solids);
        let (nf, nw, ns) = (f.len(), w.len(), s.len());
        let total = nf + nw + ns;
        let mut points = Vec::with_capacity(total);
        points.extend((0..nf).map(|i| [f.x[i], f.y[i], f.z[i]]));
        points.extend((0..nw).map(|i| [w.x[i], w.y[i], w.z[i]]));
        points.extend((0..ns).map(|i| [s.x[i], s.y[i], s.z[i]]));
        let mut velocity = Vec::with_capacity(3 * total);
        for i in 0..nf {
            velocity.extend([f.ux[i], f.uy[i], f.uz[i]]);
        }
        velocity.resize(3 * (nf + nw), 0.0);
        for i in 0..ns {
            velocity.extend([s.vx[i], s.vy[i], s.vz[i]]);
        }
        let solid_density: Vec<f32> =
            s.body.iter().map(|&b| self.scene.solids.get(b as usize).map_or(0.0, |b| b.density)).collect();
        let cat = |a: &[f32], b: &[f32], c: &[f32]| -> Vec<f32> { a.iter().chain(b).chain(c).copied().collect() };
        let zero_fw = vec![0.0f32; nf + nw];
        let mut kinds = vec![kind::FLUID; nf];
        kinds.resize(nf + nw, kind::WALL);
        kinds.resize(total, kind::SOLID);
        let k = f.alpha.len();
        let mut alpha = Vec::with_capacity(k * total);
        for i in 0..nf {
            alpha.extend(f.alpha.iter().map(|a| a[i]));
        }
        alpha.resize(k * total, 0.0);
        let mut beta = Vec::with_capacity(k * total);
        for i in 0..nf {
            beta.extend(f.beta.iter().map(|b| b[i]));
        }
        beta.resize(k * total, 0.0);
        // alpha_<phase>, beta_<phase>: one component of alpha or beta each.
        let per_phase = |name: &str, all: &[Vec<f32>]| -> Vec<PointArray> {
            self.scene
                .phases
                .iter()
                .zip(all)
                .map(|(ph, v)| {
                    let mut data = v.clone();
                    data.resize(total, 0.0);
                    array(&format!("{name}_{}", ph.name), "", 1, ArrayData::F32(data))
                })
                .collect()
        };
        let alpha_named = per_phase("alpha", &f.alpha);
        let beta_named = per_phase("beta", &f.beta);
        let mut color = Vec::with_capacity(3 * total);
        for i in 0..nf {
            let mut c = [0.0f32; 3];
            for ((ph, a), b) in self.scene.phases.iter().zip(&f.alpha).zip(&f.beta) {
                for (cc, pc) in c.iter_mut().zip(ph.color) {
                    *cc += (a[i] + INNER_SHADE * b[i]) * pc;
                }
            }
            color.extend(c);
        }
        for _ in 0..nw {
            color.extend([0.6, 0.6, 0.6]);
        }
        for i in 0..ns {
            let body = self.scene.solids.get(s.body[i] as usize);
            let e = body.and_then(|b| b.porous.as_ref()).map_or(1.0, |p| p.porosity);
            let mut t = (s.saturation[i] / e).clamp(0.0, 1.0);
            let (dry, wet) = if let Some(SolidMaterial::Granular(g)) = body.map(|b| b.model) {
                // Damp sand with its moisture held fixed shows it.
                t = g.saturation.unwrap_or(t);
                (SAND_DRY_COLOR, SAND_WET_COLOR)
            } else {
                (SOLID_COLOR, WET_COLOR)
            };
            color.extend((0..3).map(|c| dry[c] + t * (wet[c] - dry[c])));
        }
        let mut arrays = vec![
            array("velocity", "m/s", 3, ArrayData::F32(velocity)),
            array("pressure", "Pa", 1, ArrayData::F32(cat(&f.pressure, &w.pressure, &s.pressure))),
            array("density", "kg/m^3", 1, ArrayData::F32(cat(&f.density, &w.density, &solid_density))),
            array("stress", "Pa", 1, ArrayData::F32(cat(&zero_fw, &s.stress, &[]))),
            array("strain_trace", "", 1, ArrayData::F32(cat(&zero_fw, &s.strain_trace, &[]))),
            array("saturation", "", 1, ArrayData::F32(cat(&zero_fw, &s.saturation, &[]))),
            array("pore_pressure", "Pa", 1, ArrayData::F32(cat(&zero_fw, &s.pore_pressure, &[]))),
            array("plastic_strain", "", 1, ArrayData::F32(cat(&zero_fw, &s.plastic_strain, &[]))),
            array("alpha", "", k, ArrayData::F32(alpha)),
            array("beta", "", k, ArrayData::F32(beta)),
            array("color", "", 3, ArrayData::F32(color)),
            array("kind", "", 1, ArrayData::U8(kinds)),
            array("id", "", 1, ArrayData::U32(f.id.iter().chain(&w.id).chain(&s.id).copied().collect())),
        ];
        arrays.extend(alpha_named);
        arrays.extend(beta_named);
        Frame { time: self.time, step: self.step, points, arrays }
    }

    /// The rows of the walls in [`Simulation::frame`].
    pub fn wall_rows(&self) -> std::ops::Range<usize> {
        self.fluid.len()..self.fluid.len() + self.walls.len()
    }
}

/// Point arrays of a frame whose values on the walls change from frame to
/// frame (the pressure boundary's); the walls' other values and their
/// positions are constant, and a run writes them once (`walls.vtkhdf`).
pub const WALL_ARRAYS_PER_FRAME: [&str; 2] = ["pressure", "density"];
