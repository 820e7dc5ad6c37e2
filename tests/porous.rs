//! The porous coupling (issue 5; P §4-5, PHYSICS.md §4.2) against
//! conservation laws, Darcy's law and the equilibrium the model implies.
//!
//! Most tests soak a porous block standing in a small tank of liquid
//! ([`Soak`]): the block is held still (its `fixed` shape is all of it), so
//! it stays strain-free and p^pore = p_0 sum_k phi_sk (P-Eq. 9).

use porosph::pipeline::Simulation;
use porosph::scene::Scene;

/// A porous block in a tank, as a scene text.
#[derive(Clone)]
struct Soak {
    /// Particle spacing, m.
    d: f32,
    /// Absorption ratio K.
    absorption: f32,
    /// Permeability of the absorbed phase(s), m^2.
    permeability: f32,
    /// Outer pore pressure p_0k, Pa.
    outer: f32,
    /// Rest pore pressure p_0, Pa.
    rest: f32,
    /// Swelling eta.
    swelling: f32,
    /// The block is held (strain-free) rather than free.
    fixed: bool,
    /// Two phases, "red" absorbed and "green" not, mixed 1:1 (else one phase "red").
    two_phases: bool,
    /// Gravity, m/s^2.
    gravity: f32,
    /// The liquid covers the block (else it reaches half its height).
    covered: bool,
    /// Wet solid particles gain the absorbed mass.
    gains_mass: bool,
}

impl Default for Soak {
    fn default() -> Self {
        Soak {
            d: 0.02,
            absorption: 1.0,
            permeability: 1e-7,
            outer: 2.5e4,
            rest: 5e4,
            swelling: 0.0,
            fixed: true,
            two_phases: false,
            gravity: -9.81,
            covered: true,
            gains_mass: false,
        }
    }
}

impl Soak {
    fn text(&self) -> String {
        let d = self.d;
        let (phases, fractions) = if self.two_phases {
            (
                "[[phase]]\nname = \"red\"\ndensity = 1000.0\nviscosity = 1.0\n\
                 [[phase]]\nname = \"green\"\ndensity = 1000.0\nviscosity = 1.0\n",
                "{ red = 0.5, green = 0.5 }",
            )
        } else {
            ("[[phase]]\nname = \"red\"\ndensity = 1000.0\nviscosity = 1.0\n", "{ red = 1.0 }")
        };
        let level = if self.covered { 0.16 } else { 0.05 };
        let fixed = if self.fixed { "fixed = { box = { min = [0.1, 0.0, 0.0], max = [0.2, 0.1, 0.1] } }" } else { "" };
        format!(
            "[simulation]\nparticle_spacing = {d}\nend_time = 100.0\nmax_dt = 0.002\ngravity = [0.0, {g}, 0.0]\n\
             {phases}\
             [[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.3, 0.1] }}\ncontainer = true\n\
             [[fluid]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, {level}, 0.1] }}\nfractions = {fractions}\n\
             [[solid]]\nname = \"block\"\nbox = {{ min = [0.1, 0.0, 0.0], max = [0.2, 0.1, 0.1] }}\n\
             density = 600.0\nshear_modulus = 2e4\nlame_lambda = 1e4\n{fixed}\n\
             [solid.porous]\nporosity = 0.6\nrest_pore_pressure = {rest}\nbiot_modulus = 4.9e4\n\
             swelling = {eta}\ncapillarity = 2.0\nabsorption = {k}\ngains_mass = {gm}\n\
             [solid.porous.phase.red]\npermeability = {kw}\nouter_pore_pressure = {outer}\n",
            g = self.gravity,
            rest = self.rest,
            eta = self.swelling,
            k = self.absorption,
            kw = self.permeability,
            outer = self.outer,
            gm = self.gains_mass,
        )
    }

    fn simulation(&self) -> Simulation {
        let scene = Scene::from_toml_str(&self.text(), "<porous test>").expect("scene");
        Simulation::new(scene)
    }
}

fn run_until(sim: &mut Simulation, t: f64) {
    while sim.time < t {
        if let Err(e) = sim.step() {
            panic!("{e}");
        }
    }
}

/// Mean saturation sum_k phi_sk over the solid particles.
fn mean_saturation(sim: &Simulation) -> f64 {
    let s = &sim.solids.saturation;
    s.iter().map(|&x| f64::from(x)).sum::<f64>() / s.len() as f64
}

/// Inner volume of phase 0, m^3.
fn inner_volume(sim: &Simulation) -> f64 {
    sim.phase_volumes_split().1[0]
}

/// Mass: every phase's total (outer + inner) mass is conserved while a
/// block absorbs for 2,000 steps, to 1e-8 (issue 5 asked for 1e-6;
/// measured 6.8e-10, the rounding of each particle's f32 sum of pair
/// fluxes; 3.5e-8 when the fractions were f32 alone, whose rounding at
/// alpha = 1 is biased, `porosph_kernels::phases::join`), and a phase the
/// solid does not absorb never gets an inner fraction:
/// beta of "green" stays exactly 0 on every particle at every step.
#[test]
fn phase_mass_is_conserved_and_only_the_absorbed_phase_enters() {
    let mut sim = Soak { two_phases: true, ..Soak::default() }.simulation();
    let m0 = sim.phase_masses();
    let mut worst = [0.0f64; 2];
    for step in 0..2000 {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        let m = sim.phase_masses();
        for k in 0..2 {
            worst[k] = worst[k].max(((m[k] - m0[k]) / m0[k]).abs());
        }
        assert!(sim.fluid.beta[1].iter().all(|&b| b == 0.0), "green entered the solid at step {step}");
    }
    let (outer, inner) = sim.phase_volumes_split();
    println!(
        "2000 steps, t = {:.3} s: red inner volume {:.3e} m^3 ({:.1} % of red), relative mass drift red {:.2e}, green {:.2e}",
        sim.time,
        inner[0],
        100.0 * inner[0] / (inner[0] + outer[0]),
        worst[0],
        worst[1]
    );
    assert!(inner[0] > 0.05 * (inner[0] + outer[0]), "the block absorbed too little to test anything");
    assert!(worst[0] <= 1e-8 && worst[1] <= 1e-8, "mass drift {worst:?}");
}

/// Equilibrium (PHYSICS.md §4.2): absorption stops where p^pore = p_0k,
/// so a strain-free block in contact with the liquid saturates at
/// sum_k phi = p_0k / p_0 (issue 5: within 5 %). Checked for two ratios,
/// after the inner volume has stopped growing (under 1 % in the last 0.5 s).
#[test]
fn strain_free_block_saturates_at_outer_over_rest_pore_pressure() {
    for outer in [2.5e4f32, 1.5e4] {
        let soak = Soak { outer, absorption: 4.0, permeability: 4e-7, ..Soak::default() };
        let mut sim = soak.simulation();
        let expected = f64::from(outer / soak.rest);
        let mut t = 0.5;
        let mut last = 0.0;
        loop {
            run_until(&mut sim, t);
            let v = inner_volume(&sim);
            let s = mean_saturation(&sim);
            println!("p0k/p0 = {expected:.2}: t = {t:.1} s, mean saturation {s:.4}, inner volume {v:.4e} m^3");
            if t >= 1.0 && (v - last).abs() <= 0.01 * v || t >= 4.0 {
                break;
            }
            last = v;
            t += 0.5;
        }
        let s = mean_saturation(&sim);
        let err = (s - expected) / expected;
        println!("p0k/p0 = {expected:.2}: mean saturation {s:.4} ({:+.1} %)", 100.0 * err);
        assert!(err.abs() <= 0.05, "mean saturation {s} vs p0k/p0 = {expected}");
    }
}

/// Darcy's law (P-Eq. 1): in a saturated slab held at a pore-pressure
/// gradient, the inner flux of the fluid, e u (the solid is at rest),
/// matches q = -(k_w / mu) grad p^pore within 5 % (issue 5).
///
/// The slab (0.2 x 0.1 x 0.1 m, d = 1 cm) is 20 one-layer regions of one
/// body whose rest pore pressures p_0 rise linearly along x, so that
/// p^pore = p_0(x) sum phi is a linear field; it is filled with fully
/// inner fluid particles (beta = 1, one per lattice cell, placed between
/// the solid particles), so sum phi is uniform inside. No gravity, no
/// absorption (K = 0). After one step every inner particle moves with the
/// Darcy velocity of its solid neighbours (P-Eqs. 10, 16). The reference
/// gradient is the least-squares slope of the solids' p^pore along x over
/// the slab's interior (2 H from every face); the measured flux is the
/// mean e u_x of the inner particles there.
#[test]
fn inner_flux_follows_darcy() {
    let d = 0.01f32;
    let (kw, mu, e) = (2e-8f32, 1.0f32, 0.6f32);
    let mut text = format!(
        "[simulation]\nparticle_spacing = {d}\nend_time = 1.0\nmax_dt = 0.001\ngravity = [0.0, 0.0, 0.0]\n\
         [[phase]]\nname = \"red\"\ndensity = 1000.0\nviscosity = {mu}\n"
    );
    for layer in 0..20 {
        let x0 = layer as f32 * d;
        let p0 = 2e4 + 1e3 * layer as f32;
        text += &format!(
            "[[solid]]\nname = \"layer{layer}\"\nbody = \"slab\"\n\
             box = {{ min = [{x0}, 0.0, 0.0], max = [{x1}, 0.1, 0.1] }}\n\
             density = 600.0\nshear_modulus = 2e4\nlame_lambda = 1e4\n\
             fixed = {{ box = {{ min = [{x0}, 0.0, 0.0], max = [{x1}, 0.1, 0.1] }} }}\n\
             [solid.porous]\nporosity = {e}\nrest_pore_pressure = {p0}\nabsorption = 0.0\n\
             [solid.porous.phase.red]\npermeability = {kw}\nouter_pore_pressure = 0.0\n",
            x1 = x0 + d,
        );
    }
    let scene = Scene::from_toml_str(&text, "<darcy slab>").expect("scene");
    let mut sim = Simulation::new(scene);
    assert_eq!(sim.fluid.len(), 0);
    // One inner fluid particle per lattice cell, between the solid particles.
    let s = &sim.solids;
    let cells: Vec<[f32; 3]> = (0..s.len())
        .map(|i| [s.x[i] + 0.5 * d, s.y[i] + 0.5 * d, s.z[i] + 0.5 * d])
        .filter(|p| p[0] < 0.2 && p[1] < 0.1 && p[2] < 0.1)
        .collect();
    let f = &mut sim.fluid;
    for (k, p) in cells.iter().enumerate() {
        f.x.push(p[0]);
        f.y.push(p[1]);
        f.z.push(p[2]);
        f.ux.push(0.0);
        f.uy.push(0.0);
        f.uz.push(0.0);
        f.pressure.push(0.0);
        f.density.push(0.0);
        f.alpha[0].push(0.0);
        f.beta[0].push(1.0);
        f.alpha_lo[0].push(0.0);
        f.beta_lo[0].push(0.0);
        f.id.push(1_000_000 + k as u32);
    }
    sim.step().unwrap_or_else(|e| panic!("{e}"));

    let margin = 4.0 * d;
    let inside = |x: f32, y: f32, z: f32| {
        x > margin && x < 0.2 - margin && y > margin && y < 0.1 - margin && z > margin && z < 0.1 - margin
    };
    // Least-squares slope of p^pore(x) over the interior solids.
    let s = &sim.solids;
    let pts: Vec<(f64, f64)> = (0..s.len())
        .filter(|&i| inside(s.x[i], s.y[i], s.z[i]))
        .map(|i| (f64::from(s.x[i]), f64::from(s.pore_pressure[i])))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum::<f64>();
    let q_ref = -f64::from(kw / mu) * slope;
    let f = &sim.fluid;
    let inner: Vec<usize> = (0..f.len()).filter(|&i| inside(f.x[i], f.y[i], f.z[i])).collect();
    let q = inner.iter().map(|&i| f64::from(e * f.ux[i])).sum::<f64>() / inner.len() as f64;
    let transverse = inner.iter().map(|&i| f64::from(f.uy[i].abs().max(f.uz[i].abs()))).fold(0.0, f64::max);
    let err = (q - q_ref) / q_ref;
    println!(
        "grad p = {slope:.4e} Pa/m over {} solids (p^pore {:.0}..{:.0} Pa); flux e u_x = {q:.4e} m/s over {} inner \
         particles vs -k/mu grad p = {q_ref:.4e} m/s ({:+.2} %); largest |u_y|, |u_z| {transverse:.2e} m/s",
        pts.len(),
        pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min),
        pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max),
        inner.len(),
        100.0 * err
    );
    assert!(slope > 0.0, "the rest pore pressure rises along x, so must p^pore");
    assert!(err.abs() <= 0.05, "Darcy flux off by {:.1} %", 100.0 * err);
}

/// The first trend of the paper's Fig. 4: a larger absorption ratio K
/// absorbs faster (more inner volume after the same time).
#[test]
fn larger_absorption_ratio_absorbs_faster() {
    let mut v = Vec::new();
    for absorption in [1.0f32, 2.0] {
        let mut sim = Soak { absorption, ..Soak::default() }.simulation();
        run_until(&mut sim, 0.5);
        v.push(inner_volume(&sim));
        println!("K = {absorption}: inner volume at t = 0.5 s {:.4e} m^3", v.last().unwrap());
    }
    assert!(v[1] > 1.1 * v[0], "K = 2 absorbed {:.3e} m^3, K = 1 {:.3e} m^3", v[1], v[0]);
}

/// The second trend of Fig. 4: at the same k_w K (the same absorption
/// rate, P-Eq. 13), a larger permeability k_w moves the absorbed fluid
/// faster inside the solid: after the same time (0.2 s, while the block
/// still soaks) the inside of the block (its solid particles below the
/// surface layer) is wetter.
#[test]
fn larger_permeability_moves_fluid_faster_inside() {
    let mut core = Vec::new();
    for (permeability, absorption) in [(1e-7f32, 2.0f32), (4e-7, 0.5)] {
        let soak = Soak { permeability, absorption, ..Soak::default() };
        let mut sim = soak.simulation();
        run_until(&mut sim, 0.2);
        let s = &sim.solids;
        let m = soak.d + 1e-4;
        let deep: Vec<f64> = (0..s.len())
            .filter(|&i| {
                let (x, y, z) = (s.x0[i], s.y0[i], s.z0[i]);
                x > 0.1 + m && x < 0.2 - m && y < 0.1 - m && z > m && z < 0.1 - m
            })
            .map(|i| f64::from(s.saturation[i]))
            .collect();
        let c = deep.iter().sum::<f64>() / deep.len() as f64;
        println!(
            "k_w = {permeability:.0e}, K = {absorption}: saturation below the surface layer {c:.4} over {} particles, inner volume {:.4e} m^3",
            deep.len(),
            inner_volume(&sim)
        );
        core.push(c);
    }
    assert!(core[1] > 1.2 * core[0], "inside saturation {:.4} (k_w x 4) vs {:.4}", core[1], core[0]);
}

/// The third trend of Fig. 4: a larger outer pore pressure p_0k absorbs
/// more in the end (the strain-free saturation is p_0k / p_0).
#[test]
fn larger_outer_pore_pressure_absorbs_more() {
    let mut v = Vec::new();
    for outer in [1.5e4f32, 2.5e4] {
        let mut sim = Soak { outer, absorption: 4.0, permeability: 4e-7, ..Soak::default() }.simulation();
        run_until(&mut sim, 2.0);
        v.push(inner_volume(&sim));
        println!(
            "p0k = {outer:.1e} Pa: inner volume at t = 2 s {:.4e} m^3, mean saturation {:.4}",
            v.last().unwrap(),
            mean_saturation(&sim)
        );
    }
    assert!(v[1] > 1.3 * v[0], "p0k 2.5e4 absorbed {:.3e} m^3, 1.5e4 {:.3e} m^3", v[1], v[0]);
}

/// Swelling (P-Eq. 5): the pore stress -eta p^pore I of a wet porous solid
/// makes it grow; with eta = 0 it does not. A free block (no fixed part)
/// soaks in a tank without gravity; its volume is measured by the mean
/// volumetric strain tr(eps) of its particles and by the mean squared
/// distance of its particles from their centroid, against the dry start.
/// eta = 0.05 (the paper's 7.5e-4 would give a strain of 1e-3 here, too
/// close to the fluid's own pressure to tell apart): the stress
/// eta p0k = 1.25 kPa over the bulk modulus lambda + 2 mu / 3 = 23 kPa
/// predicts tr(eps) ~ 0.05 (less the Biot feedback B tr(eps)).
#[test]
fn wet_solid_swells_only_with_swelling_factor() {
    let spread = |sim: &Simulation| {
        let s = &sim.solids;
        let n = s.len() as f64;
        let c = [
            s.x.iter().map(|&v| f64::from(v)).sum::<f64>() / n,
            s.y.iter().map(|&v| f64::from(v)).sum::<f64>() / n,
            s.z.iter().map(|&v| f64::from(v)).sum::<f64>() / n,
        ];
        (0..s.len())
            .map(|i| {
                (f64::from(s.x[i]) - c[0]).powi(2)
                    + (f64::from(s.y[i]) - c[1]).powi(2)
                    + (f64::from(s.z[i]) - c[2]).powi(2)
            })
            .sum::<f64>()
            / n
    };
    let mut growth = Vec::new();
    for swelling in [0.05f32, 0.0] {
        let soak =
            Soak { swelling, fixed: false, gravity: 0.0, absorption: 4.0, permeability: 4e-7, ..Soak::default() };
        let mut sim = soak.simulation();
        let r0 = spread(&sim);
        run_until(&mut sim, 1.0);
        let trace = sim.solids.strain_trace.iter().map(|&v| f64::from(v)).sum::<f64>() / sim.solids.len() as f64;
        // Volume ratio from the mean squared radius: (r2 / r2_0)^(3/2).
        let volume = (spread(&sim) / r0).powf(1.5) - 1.0;
        println!(
            "eta = {swelling}: mean saturation {:.3}, mean tr(eps) {trace:+.4}, volume change from the spread {:+.2} %",
            mean_saturation(&sim),
            100.0 * volume
        );
        assert!(mean_saturation(&sim) > 0.3, "the block did not soak");
        growth.push((trace, volume));
    }
    let (wet, dry) = (growth[0], growth[1]);
    assert!(wet.0 > 0.02 && wet.1 > 0.02, "eta = 0.05: tr(eps) {:.4}, volume {:.4}", wet.0, wet.1);
    assert!(dry.0.abs() < 0.005 && dry.1.abs() < 0.005, "eta = 0: tr(eps) {:.4}, volume {:.4}", dry.0, dry.1);
}

/// The paper's Example 3: with `gains_mass`, a wet solid particle weighs
/// m_s0 + sum_k phi_sk rho_k V_s0. Because phi distributes each fluid
/// particle's inner volume over its solid neighbours as a partition of
/// unity (`porosph_kernels::porous`), the solid's total mass gain equals
/// the mass of the absorbed fluid (to f32 rounding of the sums).
#[test]
fn wet_solid_gains_the_absorbed_mass() {
    let soak = Soak { gains_mass: true, ..Soak::default() };
    let mut sim = soak.simulation();
    let dry: f64 = sim.solids.mass.iter().map(|&m| f64::from(m)).sum();
    run_until(&mut sim, 0.3);
    // The step sets the masses from the fluid's inner fractions at its start.
    let absorbed = 1000.0 * inner_volume(&sim);
    sim.step().unwrap_or_else(|e| panic!("{e}"));
    let wet: f64 = sim.solids.mass.iter().map(|&m| f64::from(m)).sum();
    let gain = wet - dry;
    println!("dry {dry:.5} kg, wet {wet:.5} kg: gain {gain:.5} kg vs absorbed fluid mass {absorbed:.5} kg");
    assert!(absorbed > 0.05 * dry, "too little absorbed to test");
    assert!((gain - absorbed).abs() <= 1e-4 * absorbed, "gain {gain} vs absorbed {absorbed}");
}

/// Example 5 of the paper (`scenes/example5_three_layers.toml`, as
/// shipped): the three-phase mixture starts at rest on the top layer, which
/// absorbs one of its phases. Reference: from rest, gravity gives every
/// particle g dt in the first step and the pressure solve only resists the
/// compression, so no fluid particle is faster than g t after each of the
/// first three steps (bound 1.5 g t, for the pressure's sideways push at
/// the layer's holes). Measured: 0.0198 / 0.0326 / 0.0477 m/s against g t
/// = 0.0196 / 0.0320 / 0.0465 m/s (dt 2, 1.3, 1.4 ms); before the
/// drift momentum term left out the pore drift
/// (`porosph_kernels::porous::without_phase_term`), 0.62 / 0.85 / 1.30
/// m/s: 310 m/s^2 from the momentum flux of P-Eq. 11's suction term.
#[test]
fn a_mixture_at_rest_on_an_absorbing_layer_starts_in_free_fall() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/example5_three_layers.toml");
    let text = std::fs::read_to_string(path).expect("scene file");
    let scene = Scene::from_toml_str(&text, path).expect("scene");
    let mut sim = Simulation::new(scene);
    let g = 9.81f64;
    for step in 1..=3 {
        if let Err(e) = sim.step() {
            panic!("{e}");
        }
        let f = &sim.fluid;
        let fastest = (0..f.len())
            .map(|i| f64::from((f.ux[i] * f.ux[i] + f.uy[i] * f.uy[i] + f.uz[i] * f.uz[i]).sqrt()))
            .fold(0.0, f64::max);
        let bound = 1.5 * g * sim.time;
        println!(
            "step {step}: t = {:.4} s, fastest fluid particle {fastest:.4} m/s, g t = {:.4}",
            sim.time,
            g * sim.time
        );
        assert!(fastest <= bound, "step {step}: a fluid particle at {fastest} m/s > 1.5 g t = {bound}");
    }
}
