//! Granular solids in the step (issue 18): the
//! Drucker-Prager continuum of `kernels/src/granular.rs` next to the elastic
//! model, behind one [`SolidModel`].
//!
//! A scene with a granular body runs [`Mixed`]: the elastic bodies as
//! before (Peer et al. 2018), and the granular particles as free particles
//! of the elastic model (no rest neighbours, so its implicit system is
//! their mass alone: a = F / m in the pressure solve, mobility 1/m) whose
//! predicted velocities come from the explicit continuum instead. The
//! continuum is explicit, so within one fluid step it takes sub-steps no
//! longer than [`SUBSTEP_CFL`] h / c (c the elastic wave speed), with the
//! geometry of the step's start; the pressure solve then adds the fluid's,
//! walls' and other bodies' pressure forces to the last sub-step's velocity.

use super::solid::{Current, Peer2018, SolidModel, SolidStats};
use crate::scene::{InitialStress, Scene, SolidMaterial, YieldCone};
use crate::store::SolidStore;
use glam::{Mat3, Vec3};
use porosph_kernels::blocks::BLOCK;
use porosph_kernels::drucker_prager::DruckerPrager;
use porosph_kernels::granular::{accelerate, stress_update, Grains, Material, Pairs, Viscosity, NOT_GRANULAR};

/// Sub-step length of the explicit continuum, in units of h / c.
pub const SUBSTEP_CFL: f32 = 0.25;

/// Monaghan's alpha of the granular artificial viscosity (Bui et al. 2008
/// use 0.1 to 1).
pub const ARTIFICIAL_VISCOSITY: f32 = 0.5;

/// The granular bodies of a scene.
pub struct Granular {
    /// Material of each particle (store order), or [`NOT_GRANULAR`].
    material: Vec<u32>,
    materials: Vec<Material>,
    /// sqrt((K + 4 G / 3) / rho) of each material, m/s.
    sound_speed: Vec<f32>,
    /// Porosity e of each material (0 if not porous).
    porosity: Vec<f32>,
    /// The saturation a material holds fixed (scene key `saturation`).
    fixed_saturation: Vec<Option<f32>>,
    /// Particle spacing h, m.
    h: f32,
    // Sorted scratch, kept for its capacity.
    s_material: Vec<u32>,
    s_body: Vec<u32>,
    s_mass: Vec<f32>,
    /// The particle volumes V = h^3.
    s_volume: Vec<f32>,
    s_pore: Vec<f32>,
    /// Saturation S = sum_k phi_sk / e.
    s_saturation: Vec<f32>,
    s_fixed: Vec<u32>,
    s_sigma: Vec<Mat3>,
    s_plastic: Vec<f32>,
    s_v: [Vec<Vec3>; 2],
    /// Sub-steps of the last prediction.
    pub substeps: u32,
}

impl Granular {
    /// The granular bodies of `scene` among `solids`, or `None` if it has none.
    pub fn new(scene: &Scene, solids: &SolidStore) -> Option<Self> {
        let mut materials = Vec::new();
        let mut sound_speed = Vec::new();
        let mut porosity = Vec::new();
        let mut fixed_saturation = Vec::new();
        let mut of_entry = vec![NOT_GRANULAR; scene.solids.len()];
        for (e, s) in scene.solids.iter().enumerate() {
            if let SolidMaterial::Granular(g) = s.model {
                let deg = std::f32::consts::PI / 180.0;
                let (phi, psi) = (g.friction_angle * deg, g.dilatancy_angle * deg);
                let cone_of = |c: f32| match g.yield_cone {
                    YieldCone::PlaneStrain => DruckerPrager::plane_strain_cone(phi, psi, c),
                    YieldCone::TriaxialCompression => DruckerPrager::compression_cone(phi, psi, c),
                };
                let cone = cone_of(g.cohesion);
                let bulk = s.lame_lambda + 2.0 * s.shear_modulus / 3.0;
                of_entry[e] = materials.len() as u32;
                // k_c is linear in the cohesion: the wet part's own cone.
                let wet_k_c = cone_of(g.wet_cohesion).k_c;
                materials.push(Material {
                    cone,
                    shear: s.shear_modulus,
                    bulk,
                    free_slip: g.wall_slip,
                    wet_k_c,
                    suction_n: g.suction_n,
                });
                porosity.push(s.porous.as_ref().map_or(0.0, |p| p.porosity));
                fixed_saturation.push(g.saturation);
                sound_speed.push(((bulk + 4.0 * s.shear_modulus / 3.0) / s.density).sqrt());
            }
        }
        if materials.is_empty() {
            return None;
        }
        let h = scene.simulation.particle_spacing;
        Some(Granular {
            material: solids.body.iter().map(|&b| of_entry[b as usize]).collect(),
            materials,
            sound_speed,
            porosity,
            fixed_saturation,
            h,
            s_material: Vec::new(),
            s_body: Vec::new(),
            s_mass: Vec::new(),
            s_volume: Vec::new(),
            s_pore: Vec::new(),
            s_saturation: Vec::new(),
            s_fixed: Vec::new(),
            s_sigma: Vec::new(),
            s_plastic: Vec::new(),
            s_v: [Vec::new(), Vec::new()],
            substeps: 0,
        })
    }

    /// Whether particle `i` (store order) is granular.
    pub fn is_granular(&self, i: usize) -> bool {
        self.material[i] != NOT_GRANULAR
    }

    /// The output `strain_trace` (the elastic volume strain tr(sigma) / 3K)
    /// and `stress` (von Mises, sqrt(3 J2)) of the granular particles.
    fn outputs(&self, s: &mut SolidStore) {
        for i in (0..s.len()).filter(|&i| self.is_granular(i)) {
            let m = self.materials[self.material[i] as usize];
            let sigma = s.granular_stress(i);
            let tr = sigma.x_axis.x + sigma.y_axis.y + sigma.z_axis.z;
            let dev = sigma - Mat3::from_diagonal(Vec3::splat(tr / 3.0));
            let ss = dev.x_axis.length_squared() + dev.y_axis.length_squared() + dev.z_axis.length_squared();
            s.strain_trace[i] = tr / (3.0 * m.bulk);
            s.stress[i] = (1.5 * ss).sqrt();
        }
    }

    /// The granular particles' velocities at the end of the step under
    /// gravity `g`, the continuum's stress (advanced and stored in `s`) and
    /// the pore stress `pore` (store order), written into `v` (store order);
    /// other entries of `v` are left alone.
    fn predict(&mut self, s: &mut SolidStore, g: Vec3, pore: Option<&[f32]>, dt: f32, near: &Current, v: &mut [Vec3]) {
        let n = s.len();
        let perm = near.perm;
        gather(perm, &self.material, &mut self.s_material);
        gather(perm, &s.body, &mut self.s_body);
        gather(perm, &s.fixed, &mut self.s_fixed);
        gather(perm, &s.mass, &mut self.s_mass);
        gather(perm, &s.plastic_strain, &mut self.s_plastic);
        self.s_volume.clear();
        self.s_volume.resize(n, self.h * self.h * self.h);
        match pore {
            Some(p) => gather(perm, p, &mut self.s_pore),
            None => {
                self.s_pore.clear();
                self.s_pore.resize(n, 0.0);
            }
        }
        self.s_saturation.clear();
        self.s_saturation.extend(perm.iter().map(|&i| {
            let (i, m) = (i as usize, self.material[i as usize] as usize);
            if let Some(&Some(fixed)) = self.fixed_saturation.get(m) {
                return fixed;
            }
            match self.porosity.get(m) {
                Some(&e) if e > 0.0 => (s.saturation[i] / e).clamp(0.0, 1.0),
                _ => 0.0,
            }
        }));
        self.s_sigma.clear();
        self.s_sigma.extend(perm.iter().map(|&i| s.granular_stress(i as usize)));
        for b in &mut self.s_v {
            b.clear();
            b.extend(perm.iter().map(|&i| {
                let i = i as usize;
                Vec3::new(s.vx[i], s.vy[i], s.vz[i])
            }));
        }

        let c = self.sound_speed.iter().copied().fold(0.0, f32::max);
        let steps = (dt * c / (SUBSTEP_CFL * self.h)).ceil().max(1.0) as u32;
        let dts = dt / steps as f32;
        self.substeps = steps;
        let pairs = Pairs { ss: near.ss, sb: near.sb };
        let walls = near.walls;
        let visc = Viscosity { alpha: ARTIFICIAL_VISCOSITY, sound_speed: &self.sound_speed, h: self.h };
        for _ in 0..steps {
            let grains = Grains {
                x: near.x,
                body: &self.s_body,
                material: &self.s_material,
                mass: &self.s_mass,
                volume: &self.s_volume,
                pore: &self.s_pore,
                saturation: &self.s_saturation,
            };
            let [v0, v1] = &mut self.s_v;
            stress_update(pairs, grains, walls, &self.materials, v0, &mut self.s_sigma, &mut self.s_plastic, dts);
            accelerate(pairs, grains, walls, &self.s_fixed, &self.materials, &self.s_sigma, visc, v0, v1, g, dts);
            self.s_v.swap(0, 1);
        }
        for (k, &i) in perm.iter().enumerate() {
            let i = i as usize;
            if self.is_granular(i) {
                s.set_granular_stress(i, self.s_sigma[k]);
                s.plastic_strain[i] = self.s_plastic[k];
                if s.fixed[i] == 0 {
                    v[i] = self.s_v[0][k];
                }
            }
        }
        self.outputs(s);
    }

    /// Keeps the grains out of the walls: for a grain closer than h to a
    /// wall particle b, the velocity loses its component into b, along
    /// n = (x_i - x_b) / |x_i - x_b| where v . n < 0 (frictionless and
    /// inelastic; friction stays with the wall's mirror stress), one wall
    /// particle after the other.
    ///
    /// Why: grain-wall pairs are not in the pressure solve (their wall
    /// force is the grain's own stress, module doc), so nothing answers
    /// the fluid's pressure force that pushes a grain into a wall but the
    /// mirror stress, which is zero in loose sand (the tension cut-off). A
    /// sand column collapsing into a pool (d = 1 cm, water 1 Pa s) had
    /// grains 6 mm below the floor and 14 mm outside a side wall at 2 s,
    /// outside the wall's kernel reach and lost.
    pub fn wall_contact(&self, s: &mut SolidStore, near: &Current) {
        let h2 = self.h * self.h;
        let sb = near.sb.used();
        let w = near.walls.x;
        for (k, &i) in near.perm.iter().enumerate() {
            let i = i as usize;
            if !self.is_granular(i) || s.fixed[i] != 0 {
                continue;
            }
            let (blk, q) = (&sb[k / BLOCK], k % BLOCK);
            let xi = Vec3::new(near.x[0][k], near.x[1][k], near.x[2][k]);
            let mut v = Vec3::new(s.vx[i], s.vy[i], s.vz[i]);
            for p in blk.range(q) {
                let j = blk.j[p] as usize;
                let r = xi - Vec3::new(w[0][j], w[1][j], w[2][j]);
                if r.length_squared() < h2 {
                    let n = r.normalize_or_zero();
                    let un = v.dot(n);
                    if un < 0.0 {
                        v -= un * n;
                    }
                }
            }
            (s.vx[i], s.vy[i], s.vz[i]) = (v.x, v.y, v.z);
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * (self.material.capacity()
            + self.s_material.capacity()
            + self.s_body.capacity()
            + self.s_mass.capacity()
            + self.s_volume.capacity()
            + self.s_pore.capacity()
            + self.s_saturation.capacity()
            + self.porosity.capacity()
            + 2 * self.fixed_saturation.capacity()
            + self.s_fixed.capacity()
            + self.s_plastic.capacity())
            + 36 * self.s_sigma.capacity()
            + 12 * (self.s_v[0].capacity() + self.s_v[1].capacity())
    }
}

/// Sets the stress of the granular bodies with `initial_stress =
/// "lithostatic"` (the others keep zero): sand at rest under its own weight,
/// vertical stress -rho |g| depth along gravity and K0 = 1 - sin(phi) of it
/// across (Jaky's coefficient of earth pressure at rest), tension positive.
/// The depth is below the body's own top: the highest particle of its
/// column (the particles of the body in the same lattice cell across
/// gravity) + h/2; nothing above the body loads it.
pub fn set_initial_stress(scene: &Scene, gravity: Vec3, h: f32, s: &mut SolidStore) {
    let g = gravity.length();
    if g == 0.0 {
        return;
    }
    let down = gravity / g;
    let (e1, e2) = down.any_orthonormal_pair();
    let vertical = Mat3::from_cols(down * down.x, down * down.y, down * down.z);
    let column = |x: Vec3| ((x.dot(e1) / h).floor() as i64, (x.dot(e2) / h).floor() as i64);
    for (b, solid) in scene.solids.iter().enumerate() {
        let SolidMaterial::Granular(gr) = solid.model else { continue };
        if gr.initial_stress != InitialStress::Lithostatic {
            continue;
        }
        let members: Vec<(usize, Vec3)> =
            (0..s.len()).filter(|&i| s.body[i] as usize == b).map(|i| (i, Vec3::new(s.x[i], s.y[i], s.z[i]))).collect();
        let mut top = std::collections::HashMap::new();
        for &(_, x) in &members {
            let height = -x.dot(down);
            top.entry(column(x)).and_modify(|t: &mut f32| *t = t.max(height)).or_insert(height);
        }
        let k0 = 1.0 - gr.friction_angle.to_radians().sin();
        for &(i, x) in &members {
            let depth = top[&column(x)] + 0.5 * h + x.dot(down);
            let sv = -solid.density * g * depth;
            s.set_granular_stress(i, k0 * sv * (Mat3::IDENTITY - vertical) + sv * vertical);
        }
    }
}

/// dst = src in the sorted order `perm` (sorted index -> store index).
fn gather<T: Copy>(perm: &[u32], src: &[T], dst: &mut Vec<T>) {
    dst.clear();
    dst.extend(perm.iter().map(|&i| src[i as usize]));
}

/// Elastic and granular bodies in one scene: [`Peer2018`] for all (the
/// granular particles without rest neighbours, so it moves them as free
/// masses), the granular particles' predicted velocities from [`Granular`].
pub struct Mixed {
    pub elastic: Peer2018,
    pub granular: Granular,
    v: Vec<Vec3>,
}

impl Mixed {
    pub fn new(elastic: Peer2018, granular: Granular) -> Self {
        Mixed { elastic, granular, v: Vec::new() }
    }
}

impl SolidModel for Mixed {
    fn name(&self) -> &'static str {
        "peer2018+granular"
    }

    fn deform(&mut self, solids: &mut SolidStore) {
        self.elastic.deform(solids);
        self.granular.outputs(solids);
    }

    fn predict(
        &mut self,
        solids: &mut SolidStore,
        g: Vec3,
        pore: Option<&[f32]>,
        dt: f32,
        near: &Current,
    ) -> SolidStats {
        let stats = self.elastic.predict(solids, g, pore, dt, near);
        self.v.clear();
        self.v.extend_from_slice(self.elastic.predicted());
        self.granular.predict(solids, g, pore, dt, near, &mut self.v);
        stats
    }

    fn predicted(&self) -> &[Vec3] {
        &self.v
    }

    fn substeps(&self) -> u32 {
        self.granular.substeps
    }

    fn respond(
        &mut self,
        solids: &SolidStore,
        force: &[Vec3],
        accel: &mut [Vec3],
        tolerance: f32,
        max_iterations: u32,
        last: bool,
    ) -> SolidStats {
        self.elastic.respond(solids, force, accel, tolerance, max_iterations, last)
    }

    fn mobility(&self, solids: &SolidStore, contact: &[u32], out: &mut [f32]) {
        self.elastic.mobility(solids, contact, out)
    }

    fn couples_bodies(&self) -> bool {
        self.elastic.couples_bodies()
    }

    fn wall_contact(&self, solids: &mut SolidStore, near: &Current) {
        self.granular.wall_contact(solids, near);
    }

    fn bytes(&self) -> usize {
        self.elastic.bytes() + self.granular.bytes() + 12 * self.v.capacity()
    }
}
