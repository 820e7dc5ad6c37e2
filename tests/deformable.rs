//! Deformable porous solids that hold (issue 14): soft, light, free elastic
//! bodies coupled with the pressure solve (the bodies' compliance inside
//! the Jacobi loop, `src/pipeline/pressure.rs`; solid rows with walls and
//! other bodies, `porosph_kernels::solid_rows`), at the paper's parameters
//! (P Table 2: mu 2e4 Pa, lambda 1e4 Pa, 600 kg/m^3, porous constants) and
//! the fluid's time step (max_dt 2 ms, CFL rule).
//!
//! The tests here are sized for CI (d = 2 cm where the physics allows, a
//! few seconds of simulated time). The full-size runs (d = 1 cm,
//! 5-10 s, three time steps) are the `#[ignore]`d tests at the end:
//! `cargo test --release --test deformable -- --ignored --nocapture`
//! (tens of minutes on 2 cores).

mod common;

use porosph::pipeline::Simulation;
use std::collections::HashMap;

/// P Table 2's porous block, absorbing `phase` (outer pore pressure p_0k
/// 2.5e4 Pa, p_0 5e4 Pa: strain-free saturation 0.5).
fn porous(phase: &str, swelling: f32, gains_mass: bool) -> String {
    format!(
        "[solid.porous]\nporosity = 0.6\nrest_pore_pressure = 5e4\nbiot_modulus = 4.9e4\nswelling = {swelling}\n\
         capillarity = 2.0\nabsorption = 1.0\ngains_mass = {gains_mass}\n\
         [solid.porous.phase.{phase}]\npermeability = 1e-7\nouter_pore_pressure = 2.5e4\n"
    )
}

/// A closed tank `[0, tank]` of water (1000 kg/m^3, `viscosity` Pa s) up to
/// `level`, at spacing `d` and `max_dt`, with the given `[[solid]]` tables.
fn pool(d: f32, max_dt: f32, tank: [f32; 3], level: f32, viscosity: f32, solids: &str) -> String {
    let [tx, ty, tz] = tank;
    format!(
        "[simulation]\nparticle_spacing = {d}\nend_time = 100.0\nmax_dt = {max_dt}\n\
         [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = {viscosity}\n\
         [[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [{tx}, {ty}, {tz}] }}\ncontainer = true\n\
         [[fluid]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [{tx}, {level}, {tz}] }}\nfractions = {{ water = 1.0 }}\n\
         {solids}"
    )
}

/// A soft elastic box (P Table 2: mu 2e4 Pa, lambda 1e4 Pa) of `density`.
fn soft_box(name: &str, lo: [f32; 3], hi: [f32; 3], density: f32) -> String {
    format!(
        "[[solid]]\nname = \"{name}\"\nbox = {{ min = [{}, {}, {}], max = [{}, {}, {}] }}\n\
         density = {density}\nshear_modulus = 2e4\nlame_lambda = 1e4\n",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    )
}

fn run_until(sim: &mut Simulation, t: f64, mut each: impl FnMut(&Simulation)) {
    while sim.time < t - 1e-9 {
        if let Err(e) = sim.step() {
            panic!("{e}");
        }
        each(sim);
    }
}

/// Indices of the solid particles of `[[solid]]` entry `body`.
fn body(sim: &Simulation, body: u32) -> Vec<usize> {
    (0..sim.solids.len()).filter(|&i| sim.solids.body[i] == body).collect()
}

fn mean(sim_values: impl Iterator<Item = f32>) -> f64 {
    let (s, n) = sim_values.fold((0.0f64, 0usize), |(s, n), v| (s + f64::from(v), n + 1));
    s / n.max(1) as f64
}

/// The height at which the fluid's own pressure would vanish, from the
/// fluid particles with x outside `[x_lo, x_hi]` more than 3 d below the
/// geometric free surface there: mean of y + p / (rho g) (as in
/// `tests/solid_fluid.rs`; the fluid's free surface sits about 0.45 d below
/// it, an SPH offset that shrinks with d).
fn hydrostatic_surface(sim: &Simulation, x_lo: f32, x_hi: f32, d: f32) -> f32 {
    let f = &sim.fluid;
    let mut top: HashMap<(i32, i32), f32> = HashMap::new();
    let away = |i: usize| f.x[i] < x_lo || f.x[i] > x_hi;
    for i in (0..f.len()).filter(|&i| away(i)) {
        let e = top.entry(((f.x[i] / d) as i32, (f.z[i] / d) as i32)).or_insert(f32::MIN);
        *e = e.max(f.y[i]);
    }
    let level = top.values().sum::<f32>() / top.len() as f32 + 0.5 * d;
    let deep: Vec<usize> = (0..f.len()).filter(|&i| away(i) && f.y[i] < level - 3.0 * d).collect();
    deep.iter().map(|&i| f.y[i] + f.pressure[i] / (1000.0 * 9.81)).sum::<f32>() / deep.len() as f32
}

/// Kinetic energy of the solid particles, J.
fn solid_kinetic_energy(sim: &Simulation) -> f64 {
    let s = &sim.solids;
    (0..s.len())
        .map(|i| 0.5 * f64::from(s.mass[i]) * f64::from(s.vx[i].powi(2) + s.vy[i].powi(2) + s.vz[i].powi(2)))
        .sum()
}

/// What a floating-slab run measured.
struct Floating {
    /// Mean immersion below the hydrostatic surface over the second half, m.
    immersion: f64,
    /// Mean solid kinetic energy over the first and the last quarter, J.
    energy_early: f64,
    energy_late: f64,
}

/// A free dry slab 0.2 x 0.06 x 0.2 m of 600 kg/m^3 (mu 2e4 Pa) floating
/// in a 0.4 x 0.3 x 0.4 m tank of water (1 Pa s, P Table 2's range, so the
/// heave is damped), placed with 0.035 m of its 0.06 m under the surface,
/// run for `t_end` at `max_dt`.
fn floating_slab(max_dt: f32, t_end: f64) -> Floating {
    let d = 0.01;
    let slab = soft_box("slab", [0.1, 0.115, 0.1], [0.3, 0.175, 0.3], 600.0);
    let mut sim = Simulation::new(common::scene_text(&pool(d, max_dt, [0.4, 0.3, 0.4], 0.15, 1.0, &slab)));
    let y0 = sim.solids.y0.iter().copied().fold(f32::MAX, f32::min);
    let bottom_layer: Vec<usize> = (0..sim.solids.len()).filter(|&i| sim.solids.y0[i] < y0 + 0.5 * d).collect();
    let (mut depth, mut early, mut late) = (Vec::new(), Vec::new(), Vec::new());
    run_until(&mut sim, t_end, |sim| {
        let bottom = mean(bottom_layer.iter().map(|&i| sim.solids.y[i])) as f32 - 0.5 * d;
        if sim.time > 0.5 * t_end {
            depth.push(f64::from(hydrostatic_surface(sim, 0.07, 0.33, d) - bottom));
        }
        if sim.time < 0.25 * t_end {
            early.push(solid_kinetic_energy(sim));
        } else if sim.time > 0.75 * t_end {
            late.push(solid_kinetic_energy(sim));
        }
    });
    let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    Floating { immersion: avg(&depth), energy_early: avg(&early), energy_late: avg(&late) }
}

/// Floating (the first criterion, CI size: 2 s): the slab floats
/// with 0.6 of its height below the hydrostatic surface (Archimedes, rho_s
/// / rho_w = 0.6) within 5 %, its kinetic energy decaying.
#[test]
fn free_soft_slab_floats_at_the_archimedes_depth() {
    let f = floating_slab(0.002, 2.0);
    let expected = 0.6 * 0.06;
    println!(
        "slab: immersion {:.2} mm vs Archimedes {:.2} mm ({:+.2} %); solid kinetic energy {:.3e} J (first 0.5 s) -> {:.3e} J (last 0.5 s)",
        1e3 * f.immersion,
        1e3 * expected,
        100.0 * (f.immersion / expected - 1.0),
        f.energy_early,
        f.energy_late
    );
    assert!((f.immersion / expected - 1.0).abs() < 0.05);
    assert!(f.energy_late < 0.5 * f.energy_early, "kinetic energy does not decay");
}

/// Compression (the second criterion): a neutrally buoyant soft
/// block (1000 kg/m^3, mu 2e4 Pa, lambda 1e4 Pa) held submerged by a few
/// particles at its centre is squeezed by the hydrostatic pressure around
/// it. Reference: linear elasticity, volumetric strain -rho g z_c / K with
/// z_c the depth of the block's centre below the hydrostatic surface and
/// K = lambda + 2 mu / 3 = 2.33e4 Pa; tolerance 20 % (the issue's). Two
/// measures are held to it: the mean corotated tr(eps) of the particles
/// below the block's outer layer, and the volume change from the
/// particles' spread about their centre ((r^2 / r0^2)^(3/2) - 1). The mean
/// tr(eps) over all particles is printed: the outer layer of a corotated
/// SPH solid reads about a third less strain than the inside under a
/// surface load (its one-sided, corrected neighbourhood; measured at
/// d = 2 cm: -0.060 in the outer layer, -0.093 to -0.097 below it, -0.096
/// expected), and at d = 2 cm the outer layer is a third of the particles,
/// so that mean reads about -15 %. Here z_c = 0.23 m (tr(eps) -0.1: the
/// law is linear). Settled for 0.8 s, measured over the next 0.2 s.
#[test]
fn submerged_soft_block_compresses_by_the_hydrostatic_pressure() {
    let d = 0.02;
    // Held at its centre (2 x 2 x 2 particles): a compressed block is
    // denser than the water and would sink onto the floor.
    let block = soft_box("block", [0.14, 0.1, 0.14], [0.46, 0.42, 0.46], 1000.0)
        + "fixed = { box = { min = [0.28, 0.24, 0.28], max = [0.32, 0.28, 0.32] } }\n";
    let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, [0.6, 0.5, 0.6], 0.46, 1.0, &block)));
    let k = 1e4 + 2.0 * 2e4 / 3.0;
    let s = &sim.solids;
    let (lo, hi) = ([0.15f32, 0.11, 0.15], [0.45f32, 0.41, 0.45]);
    let inside: Vec<usize> = (0..s.len())
        .filter(|&i| {
            (0..3).all(|c| {
                [s.x0[i], s.y0[i], s.z0[i]][c] > lo[c] + 0.5 * d && [s.x0[i], s.y0[i], s.z0[i]][c] < hi[c] - 0.5 * d
            })
        })
        .collect();
    let spread = |sim: &Simulation| {
        let s = &sim.solids;
        let c = [mean(s.x.iter().copied()), mean(s.y.iter().copied()), mean(s.z.iter().copied())];
        (0..s.len())
            .map(|i| (0..3).map(|a| (f64::from([s.x[i], s.y[i], s.z[i]][a]) - c[a]).powi(2)).sum::<f64>())
            .sum::<f64>()
            / s.len() as f64
    };
    let r0 = spread(&sim);
    let (mut all, mut inner, mut volume, mut expected) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    run_until(&mut sim, 1.0, |sim| {
        if sim.time > 0.8 {
            let surface = f64::from(hydrostatic_surface(sim, 0.1, 0.5, d));
            let z_c = surface - mean(sim.solids.y.iter().copied());
            expected.push(-1000.0 * 9.81 * z_c / k);
            all.push(mean(sim.solids.strain_trace.iter().copied()));
            inner.push(mean(inside.iter().map(|&i| sim.solids.strain_trace[i])));
            volume.push((spread(sim) / r0).powf(1.5) - 1.0);
        }
    });
    let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (e, a, i, v) = (avg(&expected), avg(&all), avg(&inner), avg(&volume));
    let pct = |x: f64| 100.0 * (x / e - 1.0);
    println!(
        "submerged block: {} solid particles; expected -rho g z_c / K = {e:+.4}; tr(eps) below the outer layer {i:+.4} \
         ({:+.1} %), volume change from the spread {v:+.4} ({:+.1} %), mean tr(eps) of all particles {a:+.4} ({:+.1} %)",
        sim.solids.len(),
        pct(i),
        pct(v),
        pct(a)
    );
    assert!((i / e - 1.0).abs() < 0.2 && (v / e - 1.0).abs() < 0.2);
}

/// Mass of every phase (outer + inner), kg, and its largest relative
/// drift from the start over a run.
struct MassWatch {
    start: Vec<f64>,
    worst: f64,
}

impl MassWatch {
    fn new(sim: &Simulation) -> Self {
        MassWatch { start: sim.phase_masses(), worst: 0.0 }
    }

    fn check(&mut self, sim: &Simulation) {
        for (m, m0) in sim.phase_masses().iter().zip(&self.start) {
            self.worst = self.worst.max(((m - m0) / m0).abs());
        }
    }
}

/// The pore pressure equilibrium of P-Eq. 9 per solid particle:
/// (p_0 sum_k phi_sk - B tr(eps_s)) / p_0k - 1 over the particles of
/// `parts`, as (mean, mean of the magnitude).
fn pore_equilibrium(sim: &Simulation, parts: &[usize]) -> (f64, f64) {
    let s = &sim.solids;
    let r: Vec<f64> =
        parts.iter().map(|&i| f64::from(5e4 * s.saturation[i] - 4.9e4 * s.strain_trace[i]) / 2.5e4 - 1.0).collect();
    (r.iter().sum::<f64>() / r.len() as f64, r.iter().map(|x| x.abs()).sum::<f64>() / r.len() as f64)
}

/// Soak (the third criterion, CI size: d = 2 cm, 4 s): a free
/// sponge of P Table 2 (0.2 x 0.16 x 0.2 m, 600 kg/m^3, mu 2e4 Pa) with
/// `gains_mass`, dropped into a pool, and one standing in it anchored at
/// its base. References:
/// absorption stops where the pore pressure reaches the outer one, p_0
/// sum phi - B tr(eps) = p_0k (P-Eq. 9); within 5 % per particle (mean of
/// the magnitude over the solid). A sponge under water is compressed by
/// the water's pressure (and a wet one by its weight), which lowers the
/// equilibrium saturation below p_0k / p_0 = 0.5 by B tr(eps) / p_0; the
/// deviation from 0.5 is printed. Each phase's mass (outer + inner) is
/// conserved to 1e-6. At d = 2 cm the saturation of single particles
/// scatters by about 7 % around the equilibrium, in layers (0.46 and 0.50
/// in alternate rows: the inner liquid is carried by about one fluid
/// particle per two solid ones); at d = 1 cm by 2 %. So this test holds
/// the mean residual to the 5 % and the per-particle one to 10 %;
/// the d = 1 cm run (`soak_at_full_size`, ignored) holds the per-particle
/// residual to 5 %.
#[test]
fn free_and_anchored_sponges_soak_to_the_pore_pressure_equilibrium() {
    let (free, anchored) = (([0.15, 0.26, 0.1], [0.35, 0.42, 0.3]), ([0.15, 0.0, 0.1], [0.35, 0.16, 0.3]));
    for s in soak_two_sponges(0.02, [0.5, 0.5, 0.4], 0.2, free, anchored, 4.0) {
        let name = s.name;
        assert!(
            s.res.abs() < 0.05 && s.res_abs < 0.1,
            "{name}: P-Eq. 9 residual {} (per particle {})",
            s.res,
            s.res_abs
        );
        assert!(s.mass_drift < 1e-6, "{name}: mass drift {}", s.mass_drift);
    }
}

/// What a soaked sponge of [`soak_two_sponges`] measured.
struct Soaked {
    name: &'static str,
    /// P-Eq. 9 residual: mean and mean magnitude over its particles.
    res: f64,
    res_abs: f64,
    /// Largest relative drift of the water's mass (outer + inner).
    mass_drift: f64,
}

/// Two soaks in a pool (`tank`, water up to `level`, mu 1 Pa s, max_dt
/// 2 ms) of P Table 2's sponge (600 kg/m^3, swelling 7.5e-4), each for
/// `t_end`: one free with `gains_mass`, dropped from the box `free`, and
/// one standing on the floor in the box `anchored`, its bottom layer
/// `fixed`. Prints each one's saturation, strain and residuals.
fn soak_two_sponges(
    d: f32,
    tank: [f32; 3],
    level: f32,
    free: ([f32; 3], [f32; 3]),
    anchored: ([f32; 3], [f32; 3]),
    t_end: f64,
) -> Vec<Soaked> {
    let (lo, hi) = anchored;
    let base = format!(
        "fixed = {{ box = {{ min = [{}, -0.01, {}], max = [{}, {d}, {}] }} }}\n",
        lo[0] - 0.01,
        lo[2] - 0.01,
        hi[0] + 0.01,
        hi[2] + 0.01
    );
    let sponges = [
        ("free, gains mass", soft_box("sponge", free.0, free.1, 600.0) + &porous("water", 7.5e-4, true)),
        ("anchored at its base", soft_box("sponge", lo, hi, 600.0) + &base + &porous("water", 7.5e-4, false)),
    ];
    sponges
        .into_iter()
        .map(|(name, solid)| {
            let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, tank, level, 1.0, &solid)));
            let mut mass = MassWatch::new(&sim);
            run_until(&mut sim, t_end, |sim| mass.check(sim));
            let all: Vec<usize> = (0..sim.solids.len()).collect();
            let (res, res_abs) = pore_equilibrium(&sim, &all);
            let sat = mean(sim.solids.saturation.iter().copied());
            println!(
                "sponge {name}, {t_end} s at d = {d}: saturation {sat:.4} ({:+.1} % of p0k/p0), mean tr(eps) {:+.4}; \
                 P-Eq. 9 residual {:+.2} % (per particle {:.2} %); mass drift {:.1e}",
                100.0 * (sat / 0.5 - 1.0),
                mean(sim.solids.strain_trace.iter().copied()),
                100.0 * res,
                100.0 * res_abs,
                mass.worst
            );
            Soaked { name, res, res_abs, mass_drift: mass.worst }
        })
        .collect()
}

/// The squeeze set-up at d = 2 cm (max_dt 2 ms, P Table 2's sponge): a
/// 0.12 m sponge, its base clamped, in a 0.1 m deep pool of 1 Pa s water,
/// under a kinematic plate that moves by `motion` (the entries of a scene
/// `motion = [...]` list).
fn squeeze_at_2_cm(motion: &str) -> Simulation {
    let solids = soft_box("sponge", [0.14, 0.0, 0.1], [0.26, 0.12, 0.22], 600.0)
        + "fixed = { box = { min = [0.13, -0.01, 0.09], max = [0.27, 0.02, 0.23] } }\n"
        + &porous("water", 7.5e-4, false)
        + "[[solid]]\nname = \"plate\"\nbox = { min = [0.1, 0.12, 0.06], max = [0.3, 0.16, 0.26] }\n\
           density = 2000.0\nshear_modulus = 1e6\nlame_lambda = 1e6\n\
           fixed = { box = { min = [0.09, 0.11, 0.05], max = [0.31, 0.17, 0.27] } }\n"
        + &format!("motion = [{motion}]\n");
    Simulation::new(common::scene_text(&pool(0.02, 0.002, [0.4, 0.3, 0.32], 0.1, 1.0, &solids)))
}

/// Squeeze (the fourth criterion, CI size): a sponge standing in a
/// pool, its base clamped, soaks for 1 s, is compressed by a kinematic
/// plate (3 cm of its 12 cm in 0.5 s), held, and released. References:
/// while held, the squeezed sponge gives its liquid back until P-Eq. 9
/// holds at the new strain (saturation (p_0k + B tr(eps)) / p_0, less than
/// the relaxed 0.5): the mean residual within 10 % (the issue's) at the
/// end of a 3.5 s hold (the per-particle one is printed; at d = 1 cm it is
/// held to 10 % by `squeeze_at_full_size`, ignored); released, it recovers
/// at least 90 % of its height within 1 s; mass conserved to 1e-6.
#[test]
fn squeezed_sponge_gives_its_liquid_back_and_recovers() {
    let (hold_end, release_end) = (5.0, 5.5);
    let mut sim = squeeze_at_2_cm(&format!(
        "{{ from = 1.0, until = 1.5, velocity = [0.0, -0.06, 0.0] }}, \
         {{ from = {hold_end}, until = {release_end}, velocity = [0.0, 0.06, 0.0] }}"
    ));
    let sponge = body(&sim, 0);
    let top = |sim: &Simulation| sponge.iter().map(|&i| sim.solids.y[i]).fold(f32::MIN, f32::max);
    let bottom0 = sponge.iter().map(|&i| sim.solids.y[i]).fold(f32::MAX, f32::min);
    let height0 = top(&sim) - bottom0;
    let mut mass = MassWatch::new(&sim);
    run_until(&mut sim, 1.0, |sim| mass.check(sim));
    let soaked = mean(sponge.iter().map(|&i| sim.solids.saturation[i]));
    run_until(&mut sim, hold_end, |sim| mass.check(sim));
    let squeezed = top(&sim) - bottom0;
    let (res, res_abs) = pore_equilibrium(&sim, &sponge);
    let held = mean(sponge.iter().map(|&i| sim.solids.saturation[i]));
    let strain = mean(sponge.iter().map(|&i| sim.solids.strain_trace[i]));
    run_until(&mut sim, release_end + 1.0, |sim| mass.check(sim));
    let recovered = top(&sim) - bottom0;
    println!(
        "squeeze: saturation {soaked:.4} soaked, {held:.4} held at tr(eps) {strain:+.4} (P-Eq. 9: {:.4}); residual {:+.2} % \
         (per particle {:.2} %); height {:.1} mm -> {:.1} mm squeezed -> {:.1} mm 1 s after release ({:.1} %); mass drift {:.1e}",
        (2.5e4 + 4.9e4 * strain) / 5e4,
        100.0 * res,
        100.0 * res_abs,
        1e3 * height0,
        1e3 * squeezed,
        1e3 * recovered,
        100.0 * recovered / height0,
        mass.worst
    );
    assert!(held < soaked, "no liquid came out");
    assert!(res.abs() < 0.1, "P-Eq. 9 residual {res} (per particle {res_abs})");
    assert!(recovered > 0.9 * height0, "height {recovered} of {height0}");
    assert!(mass.worst < 1e-6, "mass drift {}", mass.worst);
}

/// Swelling with gravity and water around it (the fifth
/// criterion): a sponge of 1200 kg/m^3 (so that it rests, wet or dry, on
/// the floor under water) soaks with eta = 0.05 and with eta = 0.
/// Reference: the pore stress -eta p^pore I of P-Eq. 5 with p^pore =
/// p_0 sum phi - B tr(eps) (P-Eq. 9) gives K tr(eps) = eta (p_0 sum phi -
/// B tr(eps)) on top of whatever the water's pressure and the weight do,
/// so the swelling is the difference of the two runs, tr(eps) = eta p_0
/// sum phi / (K + eta B) (the formula, with the sponge's own mean
/// saturation); within 20 % (the issue's). The paper's eta = 7.5e-4 gives
/// about 1e-3, below what the water's pressure does to the strain.
#[test]
fn swelling_follows_the_pore_stress_under_water() {
    let d = 0.02;
    let run = |eta: f32| {
        let solid = soft_box("sponge", [0.1, 0.0, 0.1], [0.22, 0.1, 0.22], 1200.0) + &porous("water", eta, false);
        let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, [0.32, 0.3, 0.32], 0.16, 1.0, &solid)));
        run_until(&mut sim, 3.0, |_| {});
        (mean(sim.solids.strain_trace.iter().copied()), mean(sim.solids.saturation.iter().copied()))
    };
    let (wet, sat) = run(0.05);
    let (dry, sat0) = run(0.0);
    let k = 1e4 + 2.0 * 2e4 / 3.0;
    let expected = 0.05 * 5e4 * sat / (k + 0.05 * 4.9e4);
    let swelling = wet - dry;
    println!(
        "swelling: tr(eps) {wet:+.4} (eta 0.05, saturation {sat:.3}) vs {dry:+.4} (eta 0, saturation {sat0:.3}): {swelling:+.4} \
         vs eta p0 sum phi / (K + eta B) = {expected:+.4} ({:+.1} %)",
        100.0 * (swelling / expected - 1.0)
    );
    assert!((swelling / expected - 1.0).abs() < 0.2);
}

/// Contact (the seventh criterion, CI size: d = 2 cm, 2 s): a soft
/// block (1500 kg/m^3) resting on the floor under water with a second one
/// stacked on it. They rest on the walls and on each other through the
/// pressure solve (solid rows with wall and other-body pairs). Reference:
/// rest; neither sinks into the floor or into the other by more than 0.1 d
/// (measured between particle layers: the lower block's bottom layer and
/// the floor's inner layer, the upper's bottom layer and the lower's top
/// layer, each one spacing apart at the start; the blocks' own elastic
/// compression under the load moves neither gap).
#[test]
fn resting_and_stacked_blocks_stay_at_rest() {
    let d = 0.02;
    let solids = soft_box("lower", [0.1, 0.0, 0.06], [0.22, 0.08, 0.18], 1500.0)
        + &soft_box("upper", [0.1, 0.08, 0.06], [0.22, 0.16, 0.18], 1500.0);
    let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, [0.32, 0.3, 0.24], 0.22, 1.0, &solids)));
    let (lower, upper) = (body(&sim, 0), body(&sim, 1));
    let layer = |sim: &Simulation, parts: &[usize], y0: f32| {
        mean(parts.iter().filter(|&&i| (sim.solids.y0[i] - y0).abs() < 0.25 * d).map(|&i| sim.solids.y[i]))
    };
    let floor_layer = -0.5 * d; // the wall's inner layer
    let (lo_bottom, lo_top, up_bottom) = (0.5 * d, 0.08 - 0.5 * d, 0.08 + 0.5 * d);
    let mut worst = (0.0f64, 0.0f64);
    let mut speed = 0.0f32;
    run_until(&mut sim, 2.0, |sim| {
        if sim.time > 0.5 {
            let floor_gap = layer(sim, &lower, lo_bottom) - f64::from(floor_layer);
            let stack_gap = layer(sim, &upper, up_bottom) - layer(sim, &lower, lo_top);
            worst.0 = worst.0.max(f64::from(d) - floor_gap);
            worst.1 = worst.1.max(f64::from(d) - stack_gap);
            speed = speed.max(sim.max_speed());
        }
    });
    println!(
        "resting blocks: largest sinking into the floor {:.3} d, into each other {:.3} d; largest speed after 0.5 s {speed:.4} m/s",
        worst.0 / f64::from(d),
        worst.1 / f64::from(d)
    );
    assert!(worst.0 < 0.1 * f64::from(d) && worst.1 < 0.1 * f64::from(d));
}

// The runs at full size: d = 1 cm (the paper's scale, P §7), the
// issue's durations. `cargo test --release --test deformable -- --ignored
// --nocapture`; minutes each on 2 cores.

/// Floating at full size: 5 s at max_dt 2 ms, and the same at 1 and
/// 0.5 ms; each within 5 % of Archimedes below the hydrostatic surface,
/// all three within 5 % of each other, the kinetic energy decaying.
#[test]
#[ignore = "long: 5 s at d = 1 cm at three time steps (about 20 min on 2 cores)"]
fn floating_at_full_size_and_three_time_steps() {
    let expected = 0.6 * 0.06;
    let runs: Vec<(f32, Floating)> = [0.002f32, 0.001, 0.0005].iter().map(|&dt| (dt, floating_slab(dt, 5.0))).collect();
    for (dt, f) in &runs {
        println!(
            "max_dt {} ms: immersion {:.2} mm ({:+.2} % of Archimedes), kinetic energy {:.3e} J -> {:.3e} J",
            dt * 1e3,
            1e3 * f.immersion,
            100.0 * (f.immersion / expected - 1.0),
            f.energy_early,
            f.energy_late
        );
        assert!((f.immersion / expected - 1.0).abs() < 0.05);
        assert!(f.energy_late < 0.5 * f.energy_early);
    }
    let (lo, hi) = runs.iter().fold((f64::MAX, f64::MIN), |(a, b), (_, f)| (a.min(f.immersion), b.max(f.immersion)));
    println!("immersions within {:.2} % of each other", 100.0 * (hi / lo - 1.0));
    assert!(hi / lo - 1.0 < 0.05);
}

/// Soak at full size: the free sponge with `gains_mass` dropped into a
/// pool, and one anchored at its base (0.12 x 0.09 x 0.12 m, the issue's),
/// each 10 s at max_dt 2 ms: P-Eq. 9's equilibrium per particle within
/// 5 % (the d = 2 cm test's reference), mass to 1e-6, no step error.
#[test]
#[ignore = "long: 10 s at d = 1 cm, two sponges (about 17 min on 2 cores)"]
fn soak_at_full_size() {
    let (free, anchored) = (([0.14, 0.25, 0.09], [0.26, 0.34, 0.21]), ([0.14, 0.0, 0.09], [0.26, 0.09, 0.21]));
    for s in soak_two_sponges(0.01, [0.4, 0.45, 0.3], 0.15, free, anchored, 10.0) {
        assert!(s.res_abs < 0.05, "{}: P-Eq. 9 residual per particle {}", s.name, s.res_abs);
        assert!(s.mass_drift < 1e-6, "{}: mass drift {}", s.name, s.mass_drift);
    }
}

/// Squeeze at full size: a 0.12 m sponge, base clamped, soaked 1 s,
/// squeezed by 3 cm in 0.5 s, held 4.5 s, released: the per-particle
/// P-Eq. 9 residual within 10 % at the end of the hold; at least 90 % of
/// the height back within 1 s of the release.
#[test]
#[ignore = "long: 7.5 s at d = 1 cm (about 5 min on 2 cores)"]
fn squeeze_at_full_size() {
    let d = 0.01;
    let (hold_end, release_end) = (6.0, 6.5);
    let solids = soft_box("sponge", [0.14, 0.0, 0.09], [0.26, 0.12, 0.21], 600.0)
        + "fixed = { box = { min = [0.13, -0.01, 0.08], max = [0.27, 0.01, 0.22] } }\n"
        + &porous("water", 7.5e-4, false)
        + "[[solid]]\nname = \"plate\"\nbox = { min = [0.1, 0.13, 0.05], max = [0.3, 0.15, 0.25] }\n\
           density = 2000.0\nshear_modulus = 1e6\nlame_lambda = 1e6\n\
           fixed = { box = { min = [0.09, 0.12, 0.04], max = [0.31, 0.16, 0.26] } }\n"
        + &format!(
            "motion = [{{ from = 1.0, until = 1.5, velocity = [0.0, -0.06, 0.0] }}, \
             {{ from = {hold_end}, until = {release_end}, velocity = [0.0, 0.06, 0.0] }}]\n"
        );
    let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, [0.4, 0.4, 0.3], 0.1, 1.0, &solids)));
    let sponge = body(&sim, 0);
    let top = |sim: &Simulation| sponge.iter().map(|&i| sim.solids.y[i]).fold(f32::MIN, f32::max);
    let bottom0 = sponge.iter().map(|&i| sim.solids.y[i]).fold(f32::MAX, f32::min);
    let height0 = top(&sim) - bottom0;
    let mut mass = MassWatch::new(&sim);
    run_until(&mut sim, hold_end, |sim| mass.check(sim));
    let squeezed = top(&sim) - bottom0;
    let (res, res_abs) = pore_equilibrium(&sim, &sponge);
    let held = mean(sponge.iter().map(|&i| sim.solids.saturation[i]));
    let strain = mean(sponge.iter().map(|&i| sim.solids.strain_trace[i]));
    run_until(&mut sim, release_end + 1.0, |sim| mass.check(sim));
    let recovered = top(&sim) - bottom0;
    println!(
        "squeeze at full size: saturation {held:.4} held at tr(eps) {strain:+.4} (P-Eq. 9: {:.4}); residual {:+.2} % \
         (per particle {:.2} %); height {:.1} -> {:.1} -> {:.1} mm ({:.1} %); mass drift {:.1e}",
        (2.5e4 + 4.9e4 * strain) / 5e4,
        100.0 * res,
        100.0 * res_abs,
        1e3 * height0,
        1e3 * squeezed,
        1e3 * recovered,
        100.0 * recovered / height0,
        mass.worst
    );
    assert!(res_abs < 0.1);
    assert!(recovered > 0.9 * height0);
    assert!(mass.worst < 1e-6);
}

/// Contact at full size: a block resting on the floor with a second one
/// stacked on it, 5 s at d = 1 cm: neither sinks by more than 0.1 d.
#[test]
#[ignore = "long: 5 s at d = 1 cm (about 3 min on 2 cores)"]
fn contact_at_full_size() {
    let d = 0.01;
    let solids = soft_box("lower", [0.1, 0.0, 0.05], [0.2, 0.05, 0.15], 1500.0)
        + &soft_box("upper", [0.1, 0.05, 0.05], [0.2, 0.1, 0.15], 1500.0);
    let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, [0.3, 0.3, 0.2], 0.2, 0.01, &solids)));
    let (lower, upper) = (body(&sim, 0), body(&sim, 1));
    let layer = |sim: &Simulation, parts: &[usize], y0: f32| {
        mean(parts.iter().filter(|&&i| (sim.solids.y0[i] - y0).abs() < 0.25 * d).map(|&i| sim.solids.y[i]))
    };
    let mut worst = (0.0f64, 0.0f64);
    run_until(&mut sim, 5.0, |sim| {
        let floor_gap = layer(sim, &lower, 0.5 * d) + 0.5 * f64::from(d);
        let stack_gap = layer(sim, &upper, 0.05 + 0.5 * d) - layer(sim, &lower, 0.05 - 0.5 * d);
        worst.0 = worst.0.max(f64::from(d) - floor_gap);
        worst.1 = worst.1.max(f64::from(d) - stack_gap);
    });
    println!(
        "contact at full size: largest sinking into the floor {:.3} d, into each other {:.3} d",
        worst.0 / f64::from(d),
        worst.1 / f64::from(d)
    );
    assert!(worst.0 < 0.1 * f64::from(d) && worst.1 < 0.1 * f64::from(d));
}

/// Added mass (the eighth criterion): a clamped elastic plate
/// (L = 0.4 m, thickness H = 0.04 m, width b = 0.16 m, 1000 kg/m^3,
/// mu 4e6 Pa, lambda 0) kicked in its first bending mode oscillates slower
/// in a closed tank full of water than alone (no fluid, no gravity), both
/// at d = 1 cm, max_dt 1 ms. The water run has gravity, so that the
/// pressure at the plate (1.6-2.0 kPa) carries the suction behind it;
/// without it (an earlier version) the p >= 0 clamp cut the suction side
/// off and the result depended on how far the bodies' response converged
/// within a sweep (ratio 0.737 with 2 CG iterations per sweep, 0.383
/// solved exactly). It settles 0.3 s, then the plate gets the kick (the
/// water shares it at once: the plate keeps about M / (M + m_a)).
///
/// Reference: potential flow of this plate in this tank
/// (`scripts/plate_added_mass.py`, finite volumes): C = 0.886, 0.901,
/// 0.911 of the unbounded strip's added mass rho pi b^2 / 4 per length at
/// 10, 5, 2.5 mm cells, frequency ratio sqrt(M / (M + m_a)) = 0.514,
/// 0.511, 0.509 (M the plate's generalised mass; with the walls four times
/// as far, C 0.828 and 0.527; the thin-plate formula
/// (1 + C pi rho_w b / (4 rho_s H))^(-1/2) gives 0.491 for C = 1). Asked:
/// within 5 % of 0.509 (the plate's SPH width is uncertain by about half
/// a spacing per side, 6 % of m_a, 2.5 % of the ratio).
///
/// FAILS today (2026-12-02, not yet resolved): alone the period is 0.303 s
/// (beam theory 0.277 s); in water the tip's extrema come 0.315 and
/// 0.387 s apart (period 0.702 s, ratio 0.432: an added mass 1.5 times the
/// potential flow's), and the swing falls from 1.6 to 1.1 mm within the
/// period (alone: 9.0 and 8.7 mm). The tip's velocity alternates from step
/// to step (10-50 ms after the kick: mean 0.015 m/s, standard deviation
/// 0.031 m/s), and the plate's mid-span and the water layer just above it
/// move against each other. The deviation is 0.003 m/s with the response
/// solved exactly in every sweep, but the period is the same (0.715 s,
/// ratio 0.424, swing 1.6 then 0.75 mm): how far the response converges
/// within a sweep is not the cause. Stopping the solve only once the rows
/// hold with the exact response: 0.009 m/s, the same period (not kept).
///
/// The plate's motion is smaller than the water's own: after the kick the
/// tip moves at about 14 mm/s (1.6 mm at 9 rad/s), while water at rest in a
/// tank 0.3 m deep (this one: 0.36 m) moves at 60-65 mm/s RMS 0.1-0.5 s
/// after the start whatever the solver's tolerance (`tests/hydrostatic.rs`,
/// `tank_at_rest_per_particle`, which says where that motion comes from).
/// Two measurements (2026-12-02) point at it rather than at the coupling:
/// with the density tolerance at 1e-4 (about 160 iterations per step) the
/// plate no longer swings to time (the tip's mean y 21.27, 20.70, 21.18 mm,
/// its axis at 20 mm, at 0.150, 0.649, 1.148 s: the extrema sit at the
/// edges of the search windows, so the "period" of 0.998 s is the window,
/// not the plate); and the whole plate translated rigidly as a kinematic
/// body after the same settling gives the water a kinetic energy (of the
/// velocity difference to the same run left at rest) of 2 KE / v^2 = 17.1
/// kg at v = 0.05 m/s but 12.1 kg at 0.1 m/s, 5 ms after the start, against
/// potential flow's 11.60 kg (`scripts/plate_added_mass.py --rigid`):
/// within 4 % at the larger speed, and not linear in v, so the smaller the
/// plate's speed against the water's own motion, the more of the water's
/// motion the measurement reads as the plate's.
#[test]
#[ignore = "long: a plate in 80k water particles at d = 1 cm (about 8 min on 2 cores); fails today, see its doc"]
fn plate_oscillates_slower_in_water_by_its_added_mass() {
    let (d, length, thick, width, mu) = (0.01f32, 0.4f32, 0.04f32, 0.16f32, 4.0e6f32);
    let plate = format!(
        "[[solid]]\nname = \"plate\"\nbox = {{ min = [-0.06, 0.0, 0.0], max = [{length}, {thick}, {width}] }}\n\
         density = 1000.0\nshear_modulus = {mu}\nlame_lambda = 0.0\n\
         fixed = {{ box = {{ min = [-0.07, -0.01, -0.01], max = [0.0, 0.1, 0.2] }} }}\n"
    );
    let header = |g: f32| {
        format!(
            "[simulation]\nparticle_spacing = {d}\nend_time = 100.0\nmax_dt = 0.001\ngravity = [0.0, {g}, 0.0]\n\
             elastic_max_iterations = 3000\n[[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 0.01\n"
        )
    };
    let (lo, hi) = ([-0.06, -0.16, -0.12], [length + 0.12, thick + 0.16, width + 0.12]);
    let tank = format!(
        "[[wall]]\nbox = {{ min = [{}, {}, {}], max = [{}, {}, {}] }}\ncontainer = true\n\
         [[fluid]]\nbox = {{ min = [{}, {}, {}], max = [{}, {}, {}] }}\nfractions = {{ water = 1.0 }}\n",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    );
    // Mode shape of the clamped-free beam, k L = 1.875.
    let kl = 1.875f32;
    let k = kl / length;
    let shape = |x: f32| {
        let a = (kl.cos() + kl.cosh()) / (kl.sin() + kl.sinh());
        let kx = k * x;
        (kx.cos() - kx.cosh()) - a * (kx.sin() - kx.sinh())
    };
    // The times of the tip's first maximum, the minimum after it and the
    // maximum after that, from `settle` s on, after a kick of 0.1 m/s.
    let extrema = |scene: String, settle: f64| {
        let mut sim = Simulation::new(common::scene_text(&scene));
        let tip: Vec<usize> = (0..sim.solids.len()).filter(|&i| sim.solids.x0[i] > length - d).collect();
        let tip_y = |sim: &Simulation| mean(tip.iter().map(|&i| sim.solids.y[i]));
        run_until(&mut sim, settle, |_| {});
        for i in 0..sim.solids.len() {
            if sim.solids.x0[i] > 0.0 {
                sim.solids.vy[i] += 0.1 * shape(sim.solids.x0[i]) / shape(length);
            }
        }
        let mut series = Vec::new();
        run_until(&mut sim, settle + 1.2, |sim| series.push((sim.time - settle, tip_y(sim))));
        let arg = |from: f64, to: f64, sign: f64| {
            let w = series.iter().filter(|(t, _)| *t >= from && *t < to);
            w.max_by(|a, b| (sign * a.1).total_cmp(&(sign * b.1))).copied().expect("samples")
        };
        let first = arg(0.0, 0.3, 1.0);
        let low = arg(first.0, first.0 + 0.5, -1.0);
        let second = arg(low.0, low.0 + 0.5, 1.0);
        println!(
            "  tip from {settle} s: max {:.2} mm at {:.3} s, min {:.2} mm at {:.3} s, max {:.2} mm at {:.3} s",
            1e3 * first.1,
            first.0,
            1e3 * low.1,
            low.0,
            1e3 * second.1,
            second.0
        );
        second.0 - first.0
    };
    let air = extrema(format!("{}{plate}", header(0.0)), 0.0);
    let water = extrema(format!("{}{tank}{plate}", header(-9.81)), 0.3);
    let ratio = air / water;
    let formula = |c: f32| (1.0 + c * std::f32::consts::PI * 1000.0 * width / (4.0 * 1000.0 * thick)).powf(-0.5);
    let reference = 0.509;
    println!(
        "plate: period {air:.4} s alone, {water:.4} s in water: frequency ratio {ratio:.3} (potential flow in this \
         tank: {reference}; thin-plate formula {:.3} for C = 1)",
        formula(1.0)
    );
    assert!((ratio / reference - 1.0).abs() < 0.05, "ratio {ratio:.3} against {reference}");
}

/// Squeeze release rate (issue 34 item 3), the CI squeeze's set-up: the
/// mean saturation S(t) of the held sponge against P-Eq. 9's equilibrium
/// at its strain, S_eq = (p_0k + B tr(eps)) / p_0, every 0.05 s of the
/// hold, and the time constant of S - S_eq.
///
/// Reference, Darcy's law (P-Eqs. 1, 9, 15-19): the absorbed volume per
/// solid volume phi moves by the Darcy flux q = -(k / mu) grad p^pore with
/// p^pore = p_0 phi - B tr(eps), so at a held strain
/// d phi / dt = (p_0 k / mu) lap phi, a diffusion with c = p_0 k / mu =
/// 5e4 x 1e-7 / 1 = 5e-3 m^2/s. The sponge (0.12 x 0.12 m across, plate on
/// top, clamped base on the floor) drains through its four sides to the
/// pool, where p^pore = p_0k: the slowest mode cos(pi x / L) cos(pi z / L)
/// decays at c 2 (pi / L)^2, tau = L^2 / (2 pi^2 c) = 0.146 s at L =
/// 0.12 m. Criterion (the issue's): the fitted tau within 25 % of it.
///
/// Measured 2026-12-05 (commit after 588e018, `cargo test --release --test
/// deformable squeeze_release_time_constant -- --ignored --nocapture`, 32
/// s): it fails. The excess S - S_eq is +0.075 when the plate stops (1.6 s),
/// +0.058 at 2.0 s, +0.038 at 3.0 s, +0.026 at 5.0 s: tau = 3.25 s over the
/// hold (about 1.6 s in its first 0.4 s), 22x the Darcy estimate; the mean
/// P-Eq. 9 residual at 5 s is +5.2 % (the CI squeeze's bound is 10 %).
/// Probes (scene keys changed in a copy, not committed): permeability x10
/// (1e-6) takes the excess from +0.032 at 1.5 s to +0.007 at 2.0 s (the
/// Darcy part speeds up as it should) but the sponge's strain then drifts
/// (S_eq 0.42 at 5 s); absorption ratio K x10 starts lower (+0.041 at 1.6
/// s) and still decays with tau = 2.9 s. So the slow tail is neither the
/// bulk Darcy flux nor the surface exchange rate. The cause, measured
/// with `porous::take_inside` switched off (a temporary switch, not
/// committed): the release then follows the strain within the Darcy time
/// (excess -0.10 at 1.0 s as the plate starts, -0.023 at 1.3 s, +0.005 at
/// 1.45 s, within +-0.025 for the rest of the hold), but the soak before it
/// stops short (saturation 0.393 at 1.0 s against 0.450 with it and 0.494
/// at equilibrium). `take_inside` moves the outer share of the absorbed
/// phase inside wherever the neighbourhood is nearly all solid, whatever
/// the sign of p^pore_s - p_0k: in a squeezed sponge (p^pore above p_0k)
/// it takes back inside, every step, what the exchange emitted, and only
/// the surface band lets liquid out. Tried next (not kept): `take_inside`
/// only where the particle's exchange does not emit (Gamma_k >= 0): the
/// release then has tau = 0.37 s (+0.025 at 1.5 s, +0.007 at 2.0 s,
/// -0.0003 at 5 s; 2.5x the Darcy estimate, still outside 25 %), the soak
/// reaches 0.421 at 1.0 s (0.450 before), but two soaks of
/// `tests/porous.rs` (`strain_free_block_saturates_at_outer_over_rest_pore_pressure`,
/// `larger_outer_pore_pressure_absorbs_more`) stop with a step error: a
/// soaking block has emitting particles too (locally above p_0k), and
/// there the outer liquid left inside is what `take_inside` exists to
/// remove. What a fix needs: emission deep inside a squeezed solid that
/// leaves no pressure rows amid it (e.g. the freed liquid kept inner and
/// carried by the Darcy flux to the surface band first).
///
/// Measured again 2026-12-05 on 7ec9ce0 (same command, 32 s): tau = 3.63 s
/// (excess +0.097 at 1.5 s, +0.028 at 5 s). Probes (temporary switches and
/// counters, not committed), by ring of the sponge's rest lattice (6 x 6
/// columns at d = 2 cm: ring 0 the outer 20 columns, ring 1 the next 12,
/// ring 2 the central 4; layers above 3 cm):
/// - The soak leaves the core nearly dry: at 1.0 s saturation 0.42 / 0.50 /
///   0.15 in rings 0 / 1 / 2 (P-Eq. 9: 0.49), p^pore 21.3 / 25.5 / 7.6 kPa.
///   Ring 1 over the outer pressure while the core is 17 kPa under it: the
///   inner Darcy flux (P-Eq. 19 among the solids) barely moves liquid
///   inward either. Held, the core still takes liquid in (0.26 -> 0.31 from
///   1.5 to 3 s) while the rings release theirs, so the mean mixes an
///   inflow and an outflow.
/// - Where the emitted liquid goes (sums of the fractions moved, in particle
///   volumes h^3, per interval): 1.5-1.6 s emitted 3.5, taken back inside
///   2.1, released by N_f = 0 0.05; 2.0-2.5 s emitted 8.2, taken back 5.4,
///   released 0.7. About 60 % of every emission is recaptured by
///   `take_inside`; the rest leaves by the surface band. The fluid
///   particles half a spacing inside the side faces stay beta = 0.85-0.99
///   through the hold, and the solid ring 0 keeps +2.8 kPa at 2.0 s (ring
///   1 +3.9 kPa): the surface exchange, not the bulk, is the bottleneck. A
///   pair-form Gamma at dp = 3 kPa is about K k/mu (alpha + phi) dp
///   sum V^2 |grad W|^2 = 0.2 / s per band particle; the band holds about
///   20 fluid particles (the inner liquid is carried by particles at about
///   phi / beta = 0.45 of the lattice density) where the four side faces
///   have about 100 lattice faces, so the band gives back about 4 particle
///   volumes / s against the 100 / s that the Darcy flux through those
///   faces, k/mu x 3 kPa x (pi/L) x 2.5, carries at the start of the hold.
/// - Kept: the drained boundary of P-Eq. 19
///   (`porosph_kernels::porous::drained_boundary`): grad p^pore_s +=
///   sum_f alpha_fk h^3 (p_0k - p^pore_s) grad W_sf over the fluid
///   neighbours (the outer liquid of an absorbed phase stands for the
///   missing neighbours at p_0k; inner particles, alpha = 0, add nothing;
///   walls and the plate stay no-flow). tau = 2.70 s (excess +0.098 at 1.5
///   s, +0.053 at 2 s, +0.020 at 5 s; 3.63 s without). The interior then
///   drains (ring 1 +2.1 kPa at 2 s against +3.9) and the core fills during
///   the soak (0.18 at 1.0 s, 0.32 at 1.5 s), but the liquid piles up in
///   ring 0 (+2.8 kPa at 2 s either way), above ring 1: the surface band
///   still lets it out only at the exchange's rate. The fluid particles
///   half a spacing inside the faces keep beta 0.93-0.98 and move out at
///   less than 1 cm/s (mean outward speed within +-0.01 m/s), and about 25
///   just outside the faces keep beta 0.08-0.16, all of it counted in the
///   surface solids' phi by the partition W / N_f.
/// - Also tried, with the drained boundary (not kept): beta_k -> alpha_k
///   where the particle emits (Gamma_k < 0) and its fill is below the
///   solid's surface (smoothstep from 0.6 to 0.4): tau = 3.51 s (excess
///   +0.082 at 1.5 s, +0.051 at 2 s), the soak 0.4425 at 1.0 s; too few
///   particles ever reach fill 0.6 while emitting to matter, and it slows
///   the hold's start.
/// - Also tried, with the drained boundary (not kept): the same release
///   over the whole surface band (all of beta_k to alpha_k at fill <= 0.8,
///   a smoothstep to none at 0.9, where the particle emits), the
///   exchange done at once at the band: excess +0.034 at 1.5 s, +0.022 at
///   1.6 s (about 0.25 s), but it overshoots (-0.013 at 2 s, -0.021 at 3
///   s: the band gives back whatever it holds, whatever the Darcy flux
///   brings) and the run stops at 3.92 s, a fluid particle at the floor
///   under the sponge at 5e4 m/s: outer liquid amid the solid and the
///   floor, the pressure rows `take_inside` exists to remove.
/// - `take_inside` only where Gamma_k >= 0: tau = 0.436 s (excess +0.028
///   at 1.5 s, +0.007 at 2 s); with the drained boundary as well: tau =
///   0.273 s (excess +0.054 at 1.5 s, +0.037 at 1.55 s, +0.027 at 1.6 s,
///   +0.007 at 2 s, -0.002 at 3 s; its first 0.1 s decays at 0.14 s, the
///   Darcy rate, then slower), and the soak reaches 0.432 at 1.0 s. Both
///   still outside 25 %, and both break the soaks noted above (not rerun).
///   This interior emission is a bulk exchange at the rate K k/mu p_0 / h^2
///   (resolution dependent), not the Darcy flux, which is why it was not
///   pursued.
///
/// So the fix needs an exit at the surface that carries the Darcy flux of
/// the drained boundary: the inner liquid the Darcy flux brings to the
/// faces has to become outer as it crosses them, at the rate the flux
/// brings it (the band has about a fifth of the fluid particles the faces
/// have lattice cells), and its beta must stop counting in the surface
/// solids' phi once it is out; interior emission stays recaptured (the
/// soaks need it).
#[test]
#[ignore = "fails (issue 34 item 3 open): tau 2.70 s against Darcy's 0.146 s; 5 s at d = 2 cm, about 1 min"]
fn squeeze_release_time_constant() {
    let hold_end = 5.0;
    let mut sim = squeeze_at_2_cm("{ from = 1.0, until = 1.5, velocity = [0.0, -0.06, 0.0] }");
    let sponge = body(&sim, 0);
    let mut series = Vec::new();
    let mut t = 1.0;
    while t <= hold_end + 1e-9 {
        run_until(&mut sim, t, |_| {});
        let s = mean(sponge.iter().map(|&i| sim.solids.saturation[i]));
        let strain = mean(sponge.iter().map(|&i| sim.solids.strain_trace[i]));
        let eq = (2.5e4 + 4.9e4 * strain) / 5e4;
        println!("t {t:.2} s: saturation {s:.4}, P-Eq. 9 equilibrium {eq:.4}, excess {:+.4}", s - eq);
        series.push((t, s - eq));
        t += 0.05;
    }
    // Time constant from the excess after the plate stops (t >= 1.5 s):
    // least squares of ln(excess) over the points while it is positive
    // and above a tenth of its value at 1.5 s.
    let start = series.iter().position(|&(t, _)| t >= 1.5 - 1e-9).expect("1.5 s");
    let e0 = series[start].1;
    let pts: Vec<(f64, f64)> =
        series[start..].iter().take_while(|&&(_, e)| e > 0.1 * e0).map(|&(t, e)| (t, e.ln())).collect();
    let n = pts.len() as f64;
    let (st, se) = pts.iter().fold((0.0, 0.0), |(a, b), &(t, e)| (a + t, b + e));
    let (mt, me) = (st / n, se / n);
    let slope = pts.iter().map(|&(t, e)| (t - mt) * (e - me)).sum::<f64>()
        / pts.iter().map(|&(t, _)| (t - mt).powi(2)).sum::<f64>();
    let tau = -1.0 / slope;
    println!("excess at 1.5 s {e0:+.4}; fit over {} points: tau = {tau:.3} s (Darcy: 0.146 s)", pts.len());
    assert!((tau / 0.146 - 1.0).abs() <= 0.25, "release time constant {tau} s against Darcy's 0.146 s");
}

/// One fluid layer under a resting block (issue 34 item 4; README,
/// deformable solids): a soft block of the sponge's elastic constants (mu
/// 2e4 Pa, lambda 1e4 Pa) at 1,500 kg/m^3, 0.12 x 0.08 x 0.12 m, set one
/// spacing above the floor (d = 2 cm, max_dt 2 ms, water of 1 Pa s, the
/// CI contact test's tank and pool), so that one layer of 36 fluid
/// particles lies between it and the floor; 2 s.
///
/// Reference: squeeze-film lubrication. The block's weight in water, W =
/// (1500 - 1000) g V = 5.65 N, on a film of thickness h between plates of
/// the block's footprint (taken as the disc of the same area, R = 0.0677
/// m) makes the film thin at |dh/dt| = 2 W h^3 / (3 pi mu R^4) (Reynolds),
/// and no liquid in the film moves up or down faster than that. Asked: the
/// largest vertical speed of the layer's particles still under the block,
/// over 1.5-2 s, at most that rate at the gap the block rests at (h = the
/// block's bottom-layer height - d / 2; about 0.04 m/s at h = 9 mm).
///
/// FAILS today (measured 2026-12-05 on the branch with
/// `iisph::Divergence::local`). The layer holds the block until about 1 s
/// (its bottom layer sinks from 0.030 to 0.026 m), then 21 of the 36
/// particles are squeezed out sideways within 0.45 s at up to 0.43 m/s and
/// the bottom layer settles at 0.019 m. The 15 that stay (y = 0.004-0.006
/// m: 0.71-0.73 d from both the floor's inner wall layer at -0.01 m and
/// the block's bottom layer; each with 16 wall, 15 solid and 6 fluid
/// neighbours) move at up to 0.20 m/s over 1.5-2 s (0.12 m/s vertically;
/// the test prints 0.196 and 0.120), their vertical velocity changing sign
/// in nearly every step (3,781 sign changes among 14-16 particles in 251
/// steps): particle 841 at 1.88-1.92 s alternates y
/// 0.0044 / 0.0041 m, u_y +0.105 / -0.102 m/s, a^p_y -93 / +113 m/s^2.
/// That acceleration is the pressure of the solve, the neighbouring wall
/// rows' part (+249 / +383 m/s^2, their mean pressure 880 / 3,625 Pa)
/// against the block's rows' part (-334 / -262 m/s^2, 2,597 / 1,163 Pa),
/// the two boundaries' pressures rising in turn from step to step; u* - u
/// is g dt (viscosity nil), the particle's own row is at p = 5.6 kPa (the
/// p >= 0 clamp not involved) and at its rest density (V0/V 1.0004), and
/// there is no drift (one phase). The solve stops after 3-5 sweeps on the
/// mean errors (fluid 7.0e-4, solid 7.3e-4; the wall rows, not counted,
/// 5.5e-4) while the largest row errors there are 3.0e-3 (fluid), 3.0e-3
/// (solid) and 3.4e-3 (wall): at 0.72 d from two boundaries a 0.3 % row
/// error is a 1e-4 m position error, 0.07 m/s in a 2 ms step. The
/// configuration has a rest state: with at least 50 sweeps a step from
/// 1.8 s the layer's largest speed falls to 0.03 m/s within 8 steps and
/// 0.01 m/s by 1.96 s, particle 841 rests at y = 0.0042 m (wall rows 2,258
/// Pa, block rows 1,915 Pa, a^p_y = +9.8 m/s^2 against gravity). What the
/// Jacobi loop misses is a slow mode: the wall and block rows' common
/// pressure level under the block, which only the block's small mobility
/// sets. Tried, not kept: counting the wall rows' mean error (no change:
/// it stays below 1e-3); a full warm start instead of half the last
/// pressure (0.23 m/s); every row's error below 2e-3 (30 sweeps a step
/// against 3.9, still 0.41 m/s); below 1e-3 (52 sweeps a step: the layer
/// keeps all 36 particles and the block its 0.029 m, 0.061 m/s at most
/// after 0.5 s, but 13 times the sweeps of every step). The squeeze-out
/// itself is what lubrication asks for (the rate above is 0.46 m/s at the
/// start's h = 2 cm, falling as h^3); the solve held to 1e-3 on every
/// row, which keeps the layer and the block where they start, drains no
/// film at all, so a fix should bring the trapped layer to rest without
/// holding up the drainage.
///
/// The CI contact test (`resting_and_stacked_blocks_stay_at_rest`, no
/// layer under its blocks) prints 0.227 m/s as its largest speed after
/// 0.5 s: the same kind of motion in the fluid's bottom layer along the
/// tank's walls (particle 352 at x = 0.016-0.018 m, y = 0.012-0.014 m, u_y
/// 0.18 / 0.09 / 0.19 m/s in steps 762-764), not under the blocks.
#[test]
#[ignore = "fails (issue 34 item 4 open): the layer's vertical speed 0.12 m/s against the squeeze film's 0.041 m/s; 2 s at d = 2 cm, about 10 s"]
fn one_fluid_layer_under_a_resting_block_rests() {
    let d = 0.02f32;
    let (lo, hi) = ([0.1f32, d, 0.06f32], [0.22f32, d + 0.08, 0.18f32]);
    let block = soft_box("block", lo, hi, 1500.0);
    let mut sim = Simulation::new(common::scene_text(&pool(d, 0.002, [0.32, 0.3, 0.24], 0.22, 1.0, &block)));
    let under = |sim: &Simulation, i: usize, below: f32| {
        let f = &sim.fluid;
        f.x[i] > lo[0] && f.x[i] < hi[0] && f.z[i] > lo[2] && f.z[i] < hi[2] && f.y[i] < below
    };
    let layer0 = (0..sim.fluid.len()).filter(|&i| under(&sim, i, d)).count();
    let y0 = sim.solids.y0.iter().copied().fold(f32::MAX, f32::min);
    let bottom: Vec<usize> = (0..sim.solids.len()).filter(|&i| sim.solids.y0[i] < y0 + 0.25 * d).collect();
    let (mut fastest, mut vertical, mut flips, mut steps) = (0.0f32, 0.0f32, 0usize, 0usize);
    let (mut last_uy, mut settle, mut trapped) = (HashMap::<u32, f32>::new(), 0.0f64, 0usize);
    run_until(&mut sim, 2.0, |sim| {
        if sim.time < 1.5 {
            return;
        }
        let f = &sim.fluid;
        let floor = mean(bottom.iter().map(|&i| sim.solids.y[i])) as f32;
        let h = f64::from(floor - 0.5 * d);
        // Reynolds' squeeze film: |dh/dt| = 2 W h^3 / (3 pi mu R^4).
        let (w, r) = (500.0 * 9.81 * 0.12 * 0.08 * 0.12, (0.12f64 * 0.12 / std::f64::consts::PI).sqrt());
        settle = 2.0 * w * h.powi(3) / (3.0 * std::f64::consts::PI * 1.0 * r.powi(4));
        let layer: Vec<usize> = (0..f.len()).filter(|&i| under(sim, i, floor - 0.5 * d)).collect();
        trapped = layer.len();
        steps += 1;
        for &i in &layer {
            fastest = fastest.max((f.ux[i].powi(2) + f.uy[i].powi(2) + f.uz[i].powi(2)).sqrt());
            vertical = vertical.max(f.uy[i].abs());
            if let Some(&u) = last_uy.get(&f.id[i]) {
                flips += (u * f.uy[i] < 0.0) as usize;
            }
            last_uy.insert(f.id[i], f.uy[i]);
        }
    });
    println!(
        "one layer under a resting block: {trapped} of {layer0} particles under it at 2 s; over 1.5-2 s largest speed \
         {fastest:.3} m/s, vertical {vertical:.3} m/s, {flips} sign changes of u_y in {steps} steps; \
         squeeze film at the final gap: {settle:.3} m/s"
    );
    assert!(f64::from(vertical) <= settle, "vertical speed {vertical} m/s against the squeeze film's {settle} m/s");
}
