//! Bodies placed where users place them (issue 34 item 2): a seeded
//! generator of one- and two-body scenes in a pool, each run a few hundred
//! steps. A placement fails if a step stops (NaN or a blown-up velocity),
//! the set-up panics, or a particle leaves the closed container.
//!
//! The pool is the issue's: 0.3 x 0.16 x 0.2 m of water (1 Pa s, P Table 2)
//! in a closed container 0.3 x 0.4 x 0.2 m, max_dt 2 ms. Bodies: spheres,
//! boxes, cylinders (any axis) or the dumbbell mesh; 2-8 cm; density
//! 100-1500 kg/m^3; shear modulus 1e3-1e6 Pa (log-uniform), lambda 0.5-2
//! mu; porous (P Table 2) or not, `gains_mass` or not; centres from fully
//! submerged to two sizes above the surface, half of them (centre and size)
//! on multiples of d/2; half the scenes have a second body stacked on or
//! touching the first.
//!
//! CI runs [`thirty_placements_at_2_cm`]; `bash bench/placements.sh` runs
//! the ignored [`placement_campaign`] (500 at d = 1 cm by default) and
//! prints every failure with its scene.
//!
//! Measured 2026-12-05 (commit ba4c84b; the later commits of that day do
//! not change one-phase explicit-viscosity scenes), `bash
//! bench/placements.sh`: 3 of 500 fail (target 0), 72 min on 2 loaded
//! cores. What each is, and what became of it:
//! - seed 152 (not fixed): a porous dumbbell mesh scaled to 7.6 cm (scale
//!   0.34418: balls of r 1.7 cm, a bar of r 0.76 cm), mu 2.6 kPa, 315
//!   kg/m^3, P Table 2's sponge (capillarity 2.0), sampled as 42
//!   particles, starts submerged (centre y = 0.114). Measured (mean solid
//!   velocity, mean y of the solid particles): it rises at up to 0.41 m/s
//!   (step 80) and leaves the water entirely (mean y 0.196 at step 200,
//!   its bottom about 2 cm above the surface at 0.16), holding about 21
//!   particle volumes of absorbed water (beta-weighted velocity equal to
//!   the body's). In the air, over steps 150-230 (0.16 s), the body and
//!   its water decelerate upwards at only 2.6 m/s^2 (gravity 9.81) and
//!   accelerate sideways (z) at 3.2 m/s^2, 0.30 -> 0.82 m/s: a net force
//!   of about 0.25 N up and 0.11 N sideways on 0.034 kg with nothing to
//!   push against. Its absorbed particles clump (pairs 0.1-0.4 mm apart,
//!   "density" to 1e5-1e9 kg/m^3 on the output) and step 241 explodes.
//!   The same scene with capillarity = 0 (its body floats, centre at y =
//!   0.159-0.161 from step 210, rising at most 0.13 m/s) or without
//!   [solid.porous] (floats at 0.160-0.167) runs 300 steps.
//!   Summed per step (sum m_f a over the fluid particles, m_f = rho_fm
//!   h^3), steps 150-230, the body out of the water: the a^cap of P-Eqs.
//!   14/18 gave the fluid (-0.10, 0.25, 0.23) N and the a^pore of P-Eq. 10
//!   (0.03, 0.42, 0.03) N, both with no reaction on the solid (PHYSICS.md
//!   §4.2: the paper's momentum exchange is one way). Against gravity on
//!   the body and every particle with beta > 0 (0.013 + 0.081 kg, -0.93
//!   N) they leave (-0.07, -0.27, 0.26) N; the momentum of that set
//!   changed at (-0.09, -0.15, 0.20) N. So a^cap drives the sideways
//!   flight (a^pore's x and z are 0.03 N) and a^cap and a^pore together
//!   the slow fall: a^pore holds the absorbed water's weight up with no
//!   reaction on the body. Steps 30-80 (rising in the pool): a^cap (0.00,
//!   0.12, 0.04) N, a^pore (0.01, 1.35, 0.22) N.
//!   What was tried (2026-12-05, on a branch; none of it is in the code):
//!   - the a^cap reaction pairwise (solid s gets -m_f psi (sum_k beta_kf)
//!     V_s grad W_fs / m_s from each fluid neighbour f; the pair forces
//!     cancel, the solids' total was the fluid's to 4 digits every step):
//!     seed 152 runs 600 steps, but it rises to a mean y of 0.171 (step
//!     120), then sinks and wanders (0.08-0.10 at steps 400-600, 0.2-0.4
//!     m/s sideways), squeezed to a mean tr(eps) of -0.22: the pairwise
//!     reaction attracts each solid particle to the liquid around it. The
//!     free soaking block of `tests/porous.rs` (eta = 0) shrank to tr(eps)
//!     -0.052 (allowed 0.005): not kept.
//!   - the a^pore reaction pairwise and explicit (solid s gets the
//!     opposite of the pair share (W_fs / N_f) h^3 sum_k beta_kf rho_k
//!     (u_betak,s - u_m,f) / dt): blows up at step 258 (t = 0.078 s, the
//!     time step cut). a^pore sets the liquid to the solid's velocity in
//!     one step; an explicit reaction then changes the relative velocity
//!     by a factor -m_liquid / m_solid a step, and this sponge holds more
//!     water (0.6 of a particle at 1000 kg/m^3) than it weighs (315).
//!   - last: the a^cap reaction as a rigid motion of each body (its net
//!     force and torque; linear and angular momentum conserved, no
//!     strain) and the a^pore reaction implicit in each body's translation
//!     (the body and its pore-coupled liquid exchange momentum
//!     inelastically: Delta_b = -J_b / (M_b + M_B,b)). Seed 152 then runs
//!     (600 steps tried): it does not rise (mean y 0.116 at step 50, the
//!     start 0.114), sinks (0.036 at step 300, -0.20 m/s) and rests on the
//!     floor from step 400 (mean y 0.014-0.017, its lowest particle at
//!     0.003-0.004, below 0.07 m/s), tr(eps) -0.05. It sinks though its
//!     bulk with the water it holds (saturation 0.46) is 775 kg/m^3: the
//!     absorbed water's weight now reaches the body, and the absorbed
//!     (inner) particles have no pressure rows, so nothing buoys them;
//!     whether a saturated sponge should float here is left open. The
//!     a^pore torque stays one way. Not merged: with `gains_mass` the
//!     solid already carries the absorbed mass (m_s = m_s0 + sum_k phi_sk
//!     rho_k V_s0), and the a^pore reaction would load the same water's
//!     weight a second time; the sinking of a sponge lighter than water
//!     with its water is unexplained; and its serial per-step loops over
//!     the fluid-solid pairs would cost every porous scene. So seed 152
//!     still explodes at step 241; the forces above are the cause.
//! - seed 367 (refused since): a 2.2 cm dumbbell mesh (scale 0.10154)
//!   sampled as 2 solid particles 1 cm apart, 112 kg/m^3, submerged: it
//!   shot up at 11 m/s, later 600 m/s, and left the container (a solid
//!   particle at x = 0.55 m after 300 steps). Each particle's only
//!   neighbour is the other, so its gradient correction L_i (P-Eq. 4,
//!   PHYSICS.md §3.1) is singular (the kernel falls back to L = I) and the
//!   body has no elastic response across its axis: not a body the
//!   model can represent. The scene loader now refuses an elastic body
//!   with a free particle whose rest neighbours within 2 d do not span
//!   three dimensions, naming the [[solid]] (`solid[0]`), the particle
//!   count and the first such particle; the campaign counts a refused
//!   scene as handled ([`the_two_particle_dumbbell_is_refused`]). At d =
//!   1 cm it refuses 106 of seeds 1-500, each for a body of 1-9 particles
//!   (thin dumbbells and cylinders, spheres of 1 cm radius); at d = 2 cm
//!   15 of seeds 1-30 (bodies of 2-8 cm are 1-4 spacings), so the CI test
//!   runs the first 30 accepted seeds.
//!
//! After these changes (commit of the seed 422 fix), seeds 401-440 at d =
//! 1 cm: 0 of 40 fail, 9 refused, 181 s on 2 loaded cores; the full 500
//! were not rerun.
//! - seed 422 (fixed since): a 6.5 x 3.9 x 3.9 cm elastic box of 1,500
//!   kg/m^3, mu 1.1e5 Pa, its bottom 2.6 cm above the floor, sinks onto
//!   one fluid layer over the floor (box bottom at y = 0.0149 m, the layer
//!   at 0.005). At step 81 fluid particle 2888 (y = 0.0048, density 960,
//!   its own row at p = 0: moving between two boundaries does not change
//!   its density) lay between four floor wall rows and four rows of the
//!   box. Those rows rose in turn, a Jacobi mode of the pressure solve
//!   whose eigenvalue is beyond -1 at omega = 0.5: the box's pressure
//!   alternated 0 / 5.2e3 ... 7.7e4 Pa and the floor's 1.0e4 ... 1.0e5 /
//!   0 over the 100 sweeps, the mean solid-row error 1e-5 / 0.013 ...
//!   0.167. The loop's divergence guard (restart with a smaller omega)
//!   judged the error sweep by sweep, and the error, which counts fluid
//!   and solid rows but not wall rows, was low every other sweep, so the
//!   guard never fired; the solve stopped at max_iterations on a sweep
//!   with the floor at 0 Pa and the box at 7.7e4 Pa, which gave the
//!   particle a^p_y = -4,084 m/s^2 (-8.6 m/s in the step): it crossed
//!   the floor (y = -0.012 at step 81, -0.77 m by step 300). The guard
//!   now takes the larger of the last two sweeps' errors
//!   (`iisph::Divergence`), restarts at omega = 0.35 and converges; the
//!   scene runs 300 steps with the fastest fluid particle at 1.1 m/s
//!   (step 10) and the box resting at y = 0.0148
//!   ([`the_heavy_box_on_one_fluid_layer_keeps_its_fluid`]).
//!
//! Rerun 2026-12-06 (commit 199657e; `bash bench/placements.sh`, 2,822 s
//! on 2 quiet cores): 1 of 500 fail, 106 refused. Seed 152 now runs its
//! 300 steps (not investigated which commit changed its course). New:
//! - seed 432 (not fixed): a 6.0 x 3.4 x 4.9 cm elastic box of 119.7
//!   kg/m^3, mu 2.6e5 Pa, lambda 4.6e5 Pa, floating at the surface (y
//!   0.158-0.192, the surface at 0.16). Steps 46-56 every solve converged
//!   (2-16 sweeps, density error <= 0.001) with a largest speed falling by
//!   exactly g dt a step (1.744 -> 1.548 m/s: one particle in ballistic
//!   flight); at step 57 the prediction's CG took 85 iterations (12 in
//!   every step before) and the largest speed went to 196 m/s with the
//!   solve converged (5 sweeps); step 59 stops on 4.2e5 m/s, fluid
//!   particle 1455 near the floor (y 0.009 m). The build before this
//!   session's changes (aa339e1) fails identically, bit for bit. Frames
//!   every step (`frame_interval = 0.002`) show two defects, neither fixed:
//!   (a) the first step throws the box (90 solid particles) out of the
//!   water at a mean 2.53 m/s upwards (its bottom particles 8 mm above
//!   the top fluid layer, 2 mm into the fluid's lattice; fluid at most
//!   0.86 m/s); it flies ballistically (mean vy 2.33, 2.14, 1.96, 1.76
//!   m/s at steps 13, 24, 34, 44) to the container's ceiling (y 0.4);
//!   (b) at step 57, its top at y 0.396 and rising at 1.52 m/s, the step
//!   that first brings it within the ceiling's wall rows sends every one
//!   of its particles through the container to y = -0.012 at -194 m/s
//!   (the exact response's CG 85 iterations against 12). The solve's
//!   error counts fluid and solid rows, not wall rows (see seed 422), so a
//!   solid-wall contact in air, with no fluid between, is not judged by
//!   it.
//!
//! Both fixed 2026-12-06; seed 432 runs its 300 steps, and 2 s (the box
//! floats, its lowest layer at y = 0.160-0.161 from 0.1 s on, below 0.03
//! m/s mean):
//! - (a) the fluid kept 3/4 d from solid particles, and the pair at 0.78 d
//!   read as compression that the first solve removed: the box's speed
//!   after step 1 goes from 2.74 m/s at a gap of 0.76 d to 0.07 at 0.99 d
//!   and 0 at d (`scene::geometry::FLUID_SOLID_GAP`, now d less 1e-3 d;
//!   no example scene's particle counts change).
//!   [`the_light_box_at_the_surface_floats_where_it_is_put`].
//! - (b) a temporary print of every sweep of step 57 (from a checkpoint
//!   at step 56): the sweeps converged (5, solid rows' error 0) with the
//!   body's accelerations at most 1.1e3 m/s^2 under forces up to 50 N,
//!   the walls' rows at 8.0e5 Pa; the exact response to those forces was
//!   a mean -5.2e4 m/s^2 (a net -555 N on 0.011 kg). The sweeps see one
//!   Jacobi-preconditioned CG iteration of the response, and for this
//!   body (dt^2 k 87 times a particle's mass) one iteration moves only the
//!   pushed particles: 0.2 % of the rigid motion's momentum. With the
//!   exact response in every sweep instead, the sweeps alternated between
//!   8.5e4 Pa and 0 on the body's rows (the 30 rows of its top layer are
//!   coupled through its rigid motion, 30 times what each row's diagonal
//!   counts) and the solve stopped on a sweep at 0 Pa. Now CG's
//!   preconditioner holds each free body's rigid motions (one iteration:
//!   0.79 of the momentum) and the rows' mobility is raised to half a
//!   bound of that coupling (`porosph_kernels::rigid_modes`):
//!   [`a_stiff_light_box_thrown_at_the_ceiling_gains_no_energy`].
//!
//! Rerun after both (commit 0f1e6ed, 2026-12-06, `PLACEMENTS=400
//! PLACEMENTS_FIRST=1 bash bench/placements.sh` and `PLACEMENTS=100
//! PLACEMENTS_FIRST=401 bash bench/placements.sh`, 2,378 s and 596 s on 2
//! cores): 0 of 500 fail, 106 refused (as before).
//!
//! Three more first-step kicks of the same kind as placement 432's, found
//! outside the campaign (a layer set 0.3 d into the floor or into another
//! body starts 0.7 d from it and the first step throws it at 1.5-1.6 m/s;
//! the campaign's pools and bodies rarely overlap a wall or each other by
//! less than d/2 and more than nothing): free solid particles now keep d
//! from walls and from other bodies, and fluid d from walls
//! (`scene::geometry::SOLID_WALL_GAP`, `SOLID_SOLID_GAP`, `FLUID_WALL_GAP`;
//! [`bodies_and_fluid_placed_into_the_floor_or_into_each_other_start_at_rest`]).
//! Campaign with the solid gaps (commit 506e40e, 2026-12-06,
//! `PLACEMENTS=100 PLACEMENTS_FIRST=1` and `PLACEMENTS=150
//! PLACEMENTS_FIRST=101 bash bench/placements.sh`, 983 s and 1,203 s on 2
//! cores shared with a CI run): 0 of 250 fail, 55 refused; with the fluid
//! gap as well (commit 0545f8b, `PLACEMENTS=100 PLACEMENTS_FIRST=251`
//! and `PLACEMENTS=150 PLACEMENTS_FIRST=351`): 0 of 250 fail, 51 refused,
//! 335 s + 519 s on 2 quiet cores. So 0 of the 500 fail (106 refused).

mod common;

use common::{scene_text, with_threads};
use porosph::pipeline::Simulation;
use porosph::scene::Scene;
use std::fmt::Write;

/// SplitMix64: a small, fixed generator, so that a seed is a scene on any
/// machine and version.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [a, b).
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn coin(&mut self) -> bool {
        self.next() & 1 == 1
    }
}

const BOX: [f64; 3] = [0.3, 0.4, 0.2];

/// What the scene loader says of a body too thin for elasticity
/// (`src/scene/parse.rs`): a refusal the campaign counts as handled.
const REFUSED: &str = "do not span three dimensions";
const SURFACE: f64 = 0.16;

/// One body: its shape's TOML, its centre and its half extents (m).
struct Body {
    shape: String,
    centre: [f64; 3],
    half: [f64; 3],
}

/// A body of size (largest extent) `size` centred at `c`.
fn shape(rng: &mut Rng, size: f64, c: [f64; 3]) -> Body {
    let r = size / 2.0;
    let v = |x: [f64; 3]| format!("[{:.5}, {:.5}, {:.5}]", x[0], x[1], x[2]);
    match rng.next() % 4 {
        0 => Body { shape: format!("sphere = {{ center = {}, radius = {r:.5} }}", v(c)), centre: c, half: [r; 3] },
        1 => {
            let h = [r, r * rng.range(0.5, 1.0), r * rng.range(0.5, 1.0)];
            let (lo, hi) = ([c[0] - h[0], c[1] - h[1], c[2] - h[2]], [c[0] + h[0], c[1] + h[1], c[2] + h[2]]);
            Body { shape: format!("box = {{ min = {}, max = {} }}", v(lo), v(hi)), centre: c, half: h }
        }
        2 => {
            let axis = (rng.next() % 3) as usize;
            let radius = r * rng.range(0.4, 1.0);
            let mut half = [radius; 3];
            half[axis] = r;
            let mut base = c;
            base[axis] -= r;
            let mut a = [0.0; 3];
            a[axis] = 1.0;
            let shape = format!(
                "cylinder = {{ base = {}, axis = {}, radius = {radius:.5}, height = {size:.5} }}",
                v(base),
                v(a)
            );
            Body { shape, centre: c, half }
        }
        _ => {
            // scenes/meshes/dumbbell.obj: 0.1 x 0.1 x 0.22 m, centred at 0.
            let s = size / 0.22;
            let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/meshes/dumbbell.obj");
            let shape = format!("mesh = {{ path = \"{path}\", scale = {s:.5}, translate = {} }}", v(c));
            Body { shape, centre: c, half: [0.05 * s, 0.05 * s, r] }
        }
    }
}

/// The TOML of the body and its material.
fn material(rng: &mut Rng, name: &str, body: &Body, out: &mut String) {
    let density = rng.range(100.0, 1500.0);
    let mu = 10f64.powf(rng.range(3.0, 6.0));
    let lambda = mu * rng.range(0.5, 2.0);
    writeln!(out, "\n[[solid]]\nname = \"{name}\"\n{}", body.shape).unwrap();
    writeln!(out, "density = {density:.1}\nshear_modulus = {mu:.1}\nlame_lambda = {lambda:.1}").unwrap();
    if rng.coin() {
        // P Table 2's sponge.
        let gains = rng.coin();
        writeln!(
            out,
            "\n[solid.porous]\nporosity = 0.6\nrest_pore_pressure = 5e4\nbiot_modulus = 4.9e4\nswelling = 7.5e-4\n\
             capillarity = 2.0\nabsorption = 1.0\ngains_mass = {gains}\n\n[solid.porous.phase.water]\n\
             permeability = 1e-7\nouter_pore_pressure = 2.5e4"
        )
        .unwrap();
    }
}

/// The scene of `seed` at spacing `d`.
fn placement(seed: u64, d: f64) -> String {
    let mut rng = Rng(seed);
    let on_grid = rng.coin();
    let snap = |x: f64| if on_grid { (x / (0.5 * d)).round() * 0.5 * d } else { x };
    let size = snap(rng.range(0.02, 0.08));
    let r = size / 2.0;
    // From fully submerged (top a spacing under the surface) to two sizes
    // above it; x and z anywhere a spacing clear of the side walls.
    let y = rng.range(r + d, SURFACE + 2.0 * size);
    let c = [rng.range(r + d, BOX[0] - r - d), y, rng.range(r + d, BOX[2] - r - d)].map(snap);
    let first = shape(&mut rng, size, c);
    let mut s = String::new();
    writeln!(
        s,
        "# placement seed {seed}\n[simulation]\nparticle_spacing = {d}\nend_time = 10.0\nmax_dt = 0.002\n\
         frame_interval = 0.1\n\n[[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 1.0\n\n\
         [[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.4, 0.2] }}\ncontainer = true\n\n\
         [[fluid]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.16, 0.2] }}\nfractions = {{ water = 1.0 }}"
    )
    .unwrap();
    material(&mut rng, "first", &first, &mut s);
    if rng.coin() {
        // A second body stacked on the first, or touching it from the side
        // (x), where the container has room for it.
        let size2 = snap(rng.range(0.02, 0.08));
        let r2 = size2 / 2.0;
        let stacked = rng.coin();
        let mut c2 = first.centre;
        if stacked {
            c2[1] += first.half[1] + r2;
        } else if c2[0] + first.half[0] + 2.0 * r2 + d < BOX[0] {
            c2[0] += first.half[0] + r2;
        } else {
            c2[0] -= first.half[0] + r2;
        }
        if c2[1] + r2 + d < BOX[1] && c2[0] - r2 > d {
            let second = shape(&mut rng, size2, c2.map(snap));
            material(&mut rng, "second", &second, &mut s);
        }
    }
    s
}

/// Runs the scene of `seed` for `steps` steps: whether the scene was
/// refused (a body too thin for elasticity), or the reason it failed.
fn run_placement(seed: u64, d: f64, steps: u64) -> Result<bool, String> {
    let text = placement(seed, d);
    let scene = match Scene::from_toml_str(&text, "<placement>") {
        Ok(scene) => scene,
        // A body too thin for elasticity is refused: a correct answer.
        Err(e) if e.reason.contains(REFUSED) => return Ok(true),
        Err(e) => return Err(e.to_string()),
    };
    let r = std::panic::catch_unwind(|| {
        let mut sim = Simulation::new(scene);
        let slack = d as f32;
        for _ in 0..steps {
            sim.step().map_err(|e| e.to_string())?;
        }
        let (f, s) = (&sim.fluid, &sim.solids);
        let inside = |x: f32, y: f32, z: f32| {
            (-slack..=BOX[0] as f32 + slack).contains(&x)
                && (-slack..=BOX[1] as f32 + slack).contains(&y)
                && (-slack..=BOX[2] as f32 + slack).contains(&z)
        };
        if let Some(i) = (0..f.len()).find(|&i| !inside(f.x[i], f.y[i], f.z[i])) {
            return Err(format!("fluid particle {} outside the container at {:?}", f.id[i], [f.x[i], f.y[i], f.z[i]]));
        }
        if let Some(i) = (0..s.len()).find(|&i| !inside(s.x[i], s.y[i], s.z[i])) {
            return Err(format!("solid particle {} outside the container at {:?}", s.id[i], [s.x[i], s.y[i], s.z[i]]));
        }
        Ok(())
    });
    match r {
        Ok(r) => r.map(|()| false),
        Err(p) => Err(format!(
            "panicked: {}",
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        )),
    }
}

/// Runs `seeds`, printing each failure with its scene; the failures.
fn campaign(seeds: impl Iterator<Item = u64>, d: f64, steps: u64) -> Vec<u64> {
    let (mut failed, mut refused) = (Vec::new(), 0);
    let t = std::time::Instant::now();
    for (k, seed) in seeds.enumerate() {
        match run_placement(seed, d, steps) {
            Ok(r) => refused += r as usize,
            Err(why) => {
                println!("FAILED seed {seed}: {why}\n{}\n", placement(seed, d));
                failed.push(seed);
            }
        }
        if (k + 1) % 25 == 0 {
            eprintln!(
                "{} placements, {} failed, {refused} refused, {:.0} s",
                k + 1,
                failed.len(),
                t.elapsed().as_secs_f64()
            );
        }
    }
    println!("{refused} placements refused (a body too thin for elasticity)");
    failed
}

/// 30 fixed placements at d = 2 cm, 300 steps each (0.6 s at 2 ms): none
/// may fail. The first 30 seeds the scene loader accepts (at 2 cm about
/// half the bodies of 2-8 cm are too thin for elasticity and refused:
/// 15 of seeds 1-30).
#[test]
fn thirty_placements_at_2_cm() {
    let accepted = |&seed: &u64| match Scene::from_toml_str(&placement(seed, 0.02), "<placement>") {
        Err(e) => !e.reason.contains(REFUSED),
        Ok(_) => true,
    };
    let seeds: Vec<u64> = (1..).filter(accepted).take(30).collect();
    let failed = with_threads(2, || campaign(seeds.into_iter(), 0.02, 300));
    assert!(failed.is_empty(), "failed seeds {failed:?} (scenes above)");
}

/// Issue 34's ball, half in the water at d = 1 cm: it stopped at step 3
/// (the elastic CG diverged on a 1.6e-18 N force; `elasticity.rs`). The
/// same at y = 0.175. 50 steps, past the old failure.
#[test]
fn the_issue_34_ball_half_in_the_water_runs() {
    for y in [0.17, 0.175] {
        let text = format!(
            "[simulation]\nparticle_spacing = 0.01\nend_time = 2.0\nmax_dt = 0.002\n\n\
             [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 1.0\n\n\
             [[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.4, 0.2] }}\ncontainer = true\n\n\
             [[fluid]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.16, 0.2] }}\nfractions = {{ water = 1.0 }}\n\n\
             [[solid]]\nname = \"ball\"\nsphere = {{ center = [0.15, {y}, 0.1], radius = 0.045 }}\n\
             density = 500.0\nshear_modulus = 5.0e4\nlame_lambda = 2.0e4\n"
        );
        let mut sim = Simulation::new(scene_text(&text));
        for _ in 0..50 {
            sim.step().unwrap_or_else(|e| panic!("ball at y = {y}: {e}"));
        }
    }
}

/// Issue 34's placement 422 at d = 1 cm: a 1,500 kg/m^3 box sinks onto one
/// fluid layer over the floor; at step 81 the pressure solve stopped on a
/// growing mode of the floor's and the box's rows and a fluid particle
/// left through the floor (module doc). 120 steps, past the old failure.
#[test]
fn the_heavy_box_on_one_fluid_layer_keeps_its_fluid() {
    with_threads(2, || run_placement(422, 0.01, 120)).unwrap_or_else(|e| panic!("placement 422: {e}"));
}

/// Issue 34's placement 432 at d = 1 cm: a 6.0 x 3.4 x 4.9 cm box of 119.7
/// kg/m^3, stiff (mu 2.6e5 Pa), placed at the surface with its lowest
/// layer 7.8 mm (0.78 d) above the fluid's top layer. The first step read
/// the close pairs as compression and threw it out of the water at 2.53
/// m/s (module doc); the fluid now keeps a spacing d from solid particles
/// (`scene::geometry::FLUID_SOLID_GAP`). Reference: Archimedes, its draft
/// at rest is 119.7 / 1000 of its 3.4 cm, 4 mm, less than a spacing from
/// where it starts, so it floats where it is put: over 150 steps (0.3 s)
/// every solid particle stays slower than the free fall over one spacing,
/// sqrt(2 g d) = 0.44 m/s, and the body's mean height within d / 2 of its
/// start (measured: at most 0.26 m/s, its lowest layer falling into the
/// gap the dropped fluid layer left; 2.9 mm lower).
#[test]
fn the_light_box_at_the_surface_floats_where_it_is_put() {
    let d = 0.01f32;
    let mut sim = Simulation::new(scene_text(&placement(432, f64::from(d))));
    let mean_y = |sim: &Simulation| sim.solids.y.iter().sum::<f32>() / sim.solids.len() as f32;
    let y0 = mean_y(&sim);
    let bound = (2.0 * 9.81 * d).sqrt();
    let mut fastest = 0.0f32;
    with_threads(2, || {
        for step in 1..=150 {
            sim.step().unwrap_or_else(|e| panic!("placement 432, step {step}: {e}"));
            let s = &sim.solids;
            let v =
                (0..s.len()).map(|i| (s.vx[i].powi(2) + s.vy[i].powi(2) + s.vz[i].powi(2)).sqrt()).fold(0.0, f32::max);
            fastest = fastest.max(v);
            assert!(v < bound, "step {step}: a solid particle at {v} m/s (bound {bound})");
        }
    });
    let dy = mean_y(&sim) - y0;
    eprintln!("placement 432: fastest solid particle {fastest:.3} m/s, mean height {:+.2} mm", 1e3 * dy);
    assert!(dy.abs() < 0.5 * d, "the body moved {dy} m from its start");
}

/// Free boxes placed 3 mm (0.3 d) into the floor of a pool at d = 1 cm,
/// or into each other, and the pool's fluid itself 3 mm into the floor.
/// (1) A 1,500 kg/m^3 box of 0.1 x 0.06 x 0.1 m with
/// `min` y = -0.003 m: its own lattice put its lowest layer 0.7 d above
/// the floor's inner wall layer, and the first step read those rows as
/// compression and threw a particle to 1.59 m/s. (2) The same box on the
/// floor's lattice and a second one, 0.08 x 0.04 x 0.08 m, set 3 mm into
/// its top: 1.54 m/s. (3) No body, the fluid box's `min` y = -0.003 m:
/// the first solve ran to its cap of 100 sweeps, 1.59 m/s. Free solid
/// particles now keep a spacing d from walls and from other bodies, and
/// fluid particles from walls (`scene::geometry::SOLID_WALL_GAP`,
/// `SOLID_SOLID_GAP`, `FLUID_WALL_GAP`; the layer that is too close is
/// dropped and the rest starts 0.7 d further). Reference: from rest,
/// gravity gives g dt = 0.0196 m/s in the first 2 ms step; asked: every
/// particle (fluid and solid) below 2 g dt after step 1 (measured 0.0235,
/// 0.0216 and 0.0217 m/s; on one lattice, a spacing apart, 0.0216 and
/// 0.0215 m/s).
#[test]
fn bodies_and_fluid_placed_into_the_floor_or_into_each_other_start_at_rest() {
    let pool = "[simulation]\nparticle_spacing = 0.01\nend_time = 0.1\nmax_dt = 0.002\n\n\
                [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 1.0\n\n\
                [[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.3, 0.4, 0.2] }\ncontainer = true\n\n\
                [[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.3, 0.16, 0.2] }\nfractions = { water = 1.0 }\n";
    let solid = |name: &str, min: [f32; 3], max: [f32; 3]| {
        format!(
            "\n[[solid]]\nname = \"{name}\"\nbox = {{ min = {min:?}, max = {max:?} }}\n\
             density = 1500.0\nshear_modulus = 1e5\nlame_lambda = 1e5\n"
        )
    };
    let into_floor = solid("box", [0.1, -0.003, 0.05], [0.2, 0.06, 0.15]);
    let stacked =
        solid("low", [0.1, 0.0, 0.05], [0.2, 0.06, 0.15]) + &solid("high", [0.11, 0.057, 0.06], [0.19, 0.1, 0.14]);
    let sunk_pool = pool
        .replace("min = [0.0, 0.0, 0.0], max = [0.3, 0.16, 0.2]", "min = [0.0, -0.003, 0.0], max = [0.3, 0.16, 0.2]");
    assert_ne!(sunk_pool, pool);
    let cases = [
        ("a box 0.3 d into the floor", format!("{pool}{into_floor}")),
        ("a box 0.3 d into another", format!("{pool}{stacked}")),
        ("the fluid 0.3 d into the floor", sunk_pool),
    ];
    for (what, text) in cases {
        let mut sim = Simulation::new(scene_text(&text));
        let st = *sim.step().unwrap_or_else(|e| panic!("{what}: {e}"));
        let bound = 2.0 * 9.81 * st.dt;
        eprintln!("{what}: largest speed after step 1 {:.4} m/s (bound {bound:.4})", st.max_speed);
        assert!(st.max_speed < bound, "{what}: largest speed {} m/s after the first step", st.max_speed);
    }
}

/// Placement 432's second defect, alone: its box (119.7 kg/m^3, mu 2.6e5
/// Pa, lambda 4.6e5 Pa; 6 x 3 x 5 particles at d = 1 cm) thrown up at 1.6
/// m/s in the air hits the container's ceiling at step 14. The pressure
/// solve's sweeps saw one Jacobi-preconditioned CG iteration of the
/// body's response, 0.2 % of its rigid motion for this stiff, light body,
/// and balanced its rows against it; the exact response at the end sent
/// it down at 5.9 m/s (and in the placement through the container at
/// -194 m/s). With the rigid motions in CG's preconditioner and in the
/// rows' mobility (`porosph_kernels::rigid_modes`) it stops at the
/// ceiling and falls. Reference: energy; a fixed wall does no positive
/// work, so the body's mean kinetic and potential energy per unit mass,
/// e = |v|^2 / 2 + g y (means over its particles), never exceeds its
/// start by more than 1 % of the start's kinetic energy (symplectic
/// Euler's drift in free flight: measured -2.5e-3 J/kg over 13 steps).
/// Measured over 40 steps: +15.4 J/kg before, -0.84 J/kg now (the contact
/// takes 65 % of the 1.28 J/kg).
#[test]
fn a_stiff_light_box_thrown_at_the_ceiling_gains_no_energy() {
    let text = "[simulation]\nparticle_spacing = 0.01\nend_time = 1.0\nmax_dt = 0.002\n\n\
                [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 1.0\n\n\
                [[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.3, 0.4, 0.2] }\ncontainer = true\n\n\
                [[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.3, 0.05, 0.2] }\nfractions = { water = 1.0 }\n\n\
                [[solid]]\nname = \"box\"\nbox = { min = [0.15, 0.33, 0.04], max = [0.21, 0.36, 0.09] }\n\
                velocity = [0.0, 1.6, 0.0]\ndensity = 119.7\nshear_modulus = 260564.7\nlame_lambda = 462797.5\n";
    let mut sim = Simulation::new(scene_text(text));
    let energy = |sim: &Simulation| {
        let s = &sim.solids;
        let e: f64 = (0..s.len())
            .map(|i| 0.5 * f64::from(s.vx[i].powi(2) + s.vy[i].powi(2) + s.vz[i].powi(2)) + 9.81 * f64::from(s.y[i]))
            .sum();
        e / s.len() as f64
    };
    let e0 = energy(&sim);
    let allowed = 0.01 * 0.5 * 1.6f64.powi(2);
    let mut highest = f64::MIN;
    with_threads(2, || {
        for step in 1..=40 {
            sim.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
            let de = energy(&sim) - e0;
            highest = highest.max(de);
            assert!(de <= allowed, "step {step}: the body's energy rose by {de:.4} J/kg (allowed {allowed})");
        }
    });
    eprintln!("energy change: at most {highest:+.4} J/kg, at the end {:+.4} J/kg", energy(&sim) - e0);
}

/// The campaign of issue 34: PLACEMENTS (default 500) seeds from
/// PLACEMENTS_FIRST (default 1) at PLACEMENTS_D m (0.01), PLACEMENTS_STEPS
/// steps (300) each. `bash bench/placements.sh`.
#[test]
#[ignore]
fn placement_campaign() {
    let env = |k: &str, default: f64| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(default);
    let (n, first) = (env("PLACEMENTS", 500.0) as u64, env("PLACEMENTS_FIRST", 1.0) as u64);
    let (d, steps) = (env("PLACEMENTS_D", 0.01), env("PLACEMENTS_STEPS", 300.0) as u64);
    let failed = campaign(first..first + n, d, steps);
    println!("{} of {n} placements failed at d = {d} m, {steps} steps: {failed:?}", failed.len());
    assert!(failed.is_empty());
}

/// The generator is deterministic and every scene it writes is valid, or
/// refused for a body too thin for elasticity.
#[test]
fn placements_are_valid_scenes() {
    for seed in 1..=200 {
        assert_eq!(placement(seed, 0.02), placement(seed, 0.02));
        match Scene::from_toml_str(&placement(seed, 0.02), "<placement>") {
            Err(e) if !e.reason.contains(REFUSED) => panic!("seed {seed}: {e}\n{}", placement(seed, 0.02)),
            _ => {}
        }
    }
}

/// Issue 34's placement 367 at d = 1 cm: a 2.2 cm dumbbell sampled as 2
/// particles shot up at 11 m/s and left the container. Refused now, with
/// the [[solid]] and the reason.
#[test]
fn the_two_particle_dumbbell_is_refused() {
    let Err(e) = Scene::from_toml_str(&placement(367, 0.01), "<placement>") else {
        panic!("placement 367 accepted:\n{}", placement(367, 0.01));
    };
    assert_eq!(e.key, "solid[0]", "{e}");
    assert!(e.reason.contains("sampled as 2 particle(s)") && e.reason.contains(REFUSED), "{e}");
}
