//! Elastic solids in fluid (issue 4): a floating block settles at the
//! Archimedes immersion depth, and a block dropped into a tank keeps the
//! fluid out and the run stable.

mod common;

use common::TankWithBlock;

use glam::{Quat, Vec3};
use porosph::pipeline::Simulation;
use std::collections::HashMap;

/// The free-surface height of the fluid away from the block: per (x, z)
/// column of width d whose x is outside `[x_lo, x_hi]`, the highest
/// particle centre, averaged over the columns, plus d / 2 (a particle
/// stands for the cell around it).
fn water_level(sim: &Simulation, x_lo: f32, x_hi: f32, d: f32) -> f32 {
    let f = &sim.fluid;
    let mut top: HashMap<(i32, i32), f32> = HashMap::new();
    for i in 0..f.len() {
        if f.x[i] < x_lo || f.x[i] > x_hi {
            let e = top.entry(((f.x[i] / d) as i32, (f.z[i] / d) as i32)).or_insert(f32::MIN);
            *e = e.max(f.y[i]);
        }
    }
    top.values().sum::<f32>() / top.len() as f32 + 0.5 * d
}

/// The height at which the fluid's pressure would vanish, from the
/// particles away from the block (x outside `[x_lo, x_hi]`) more than 3 d
/// below the free surface `level`: mean of y + p / (rho g).
fn pressure_surface(sim: &Simulation, x_lo: f32, x_hi: f32, level: f32, d: f32) -> f32 {
    let f = &sim.fluid;
    let rho_g = sim.scene.phases[0].density * 9.81;
    let deep: Vec<usize> =
        (0..f.len()).filter(|&i| (f.x[i] < x_lo || f.x[i] > x_hi) && f.y[i] < level - 3.0 * d).collect();
    deep.iter().map(|&i| f.y[i] + f.pressure[i] / rho_g).sum::<f32>() / deep.len() as f32
}

/// A block of density 600 kg/m^3 (0.2 x 0.1 x 0.1 m, wide enough to float
/// upright: B / H = 2 > sqrt(6 s (1 - s)) = 1.2 for s = 0.6), placed near
/// its equilibrium (bottom 5 cm under the water) in a closed tank with fluid
/// on every side, in a fluid of viscosity 1 Pa s (the paper's range, P
/// Table 2) so the heave is damped, settled for 2 s.
///
/// Reference: Archimedes: the block floats with its bottom D = (rho_s /
/// rho_w) H = 0.06 m below the fluid's surface. Two surfaces are measured:
/// (1) the geometric one (top particle centres + d / 2, away from the
/// block) and (2) the hydrostatic one, where the fluid's own pressure away
/// from the block extrapolates to zero. The fluid puts (2) about 0.45 d
/// above (1) with or without a solid (a free-surface offset of SPH, which
/// shrinks with d), and the block's force balance is with the pressure, so
/// the test holds the depth below (2) to 5 % (the issue's) and prints both.
/// Resolution d = 1 cm (D = 6 d). Averaged over t = 1-2 s.
#[test]
fn floating_block_settles_at_the_archimedes_depth() {
    let d = 0.01f32;
    let scene = TankWithBlock {
        d,
        tank: [0.4, 0.4, 0.2],
        water: 0.2,
        viscosity: 1.0,
        lo: [0.1, 0.15, 0.05],
        hi: [0.3, 0.25, 0.15],
        density: 600.0,
        lambda: 0.0,
    }
    .text();
    let mut sim = Simulation::new(common::scene_text(&scene));
    let expected = 0.6 * 0.1f32;
    let bottom: Vec<usize> = (0..sim.solids.len()).filter(|&i| sim.solids.y0[i] < 0.15 + d).collect();
    let (mut geometric, mut hydrostatic) = (Vec::new(), Vec::new());
    while sim.time < 2.0 {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        if sim.time > 1.0 {
            let level = water_level(&sim, 0.07, 0.33, d);
            let surface = pressure_surface(&sim, 0.07, 0.33, level, d);
            let bot = bottom.iter().map(|&i| sim.solids.y[i]).sum::<f32>() / bottom.len() as f32 - 0.5 * d;
            geometric.push(level - bot);
            hydrostatic.push(surface - bot);
        }
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let (geo, hyd) = (mean(&geometric), mean(&hydrostatic));
    let (lo, hi) = hydrostatic.iter().fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    println!(
        "floating block: {} fluid + {} solid particles; immersion depth below the hydrostatic surface {:.2} mm \
         (range {:.2}-{:.2}), below the geometric surface {:.2} mm; Archimedes {:.2} mm ({:+.2} % and {:+.2} %)",
        sim.fluid.len(),
        sim.solids.len(),
        1e3 * hyd,
        1e3 * lo,
        1e3 * hi,
        1e3 * geo,
        1e3 * expected,
        100.0 * (hyd / expected - 1.0),
        100.0 * (geo / expected - 1.0)
    );
    assert!((hyd / expected - 1.0).abs() < 0.05);
}

/// Fluid particles inside a (nearly rigid) box-shaped solid: the solid's
/// rigid motion is fitted (centroid, mean particle rotation), each fluid
/// particle is taken to the rest frame, and counted if it lies inside the
/// rest box shrunk by d / 2, i.e. deeper than the solid's surface layer.
fn fluid_inside(sim: &Simulation, min: Vec3, max: Vec3, d: f32) -> usize {
    let s = &sim.solids;
    let n = s.len() as f32;
    let c = Vec3::new(s.x.iter().sum::<f32>(), s.y.iter().sum::<f32>(), s.z.iter().sum::<f32>()) / n;
    let c0 = Vec3::new(s.x0.iter().sum::<f32>(), s.y0.iter().sum::<f32>(), s.z0.iter().sum::<f32>()) / n;
    let mut q = [0.0f32; 4];
    for i in 0..s.len() {
        let qi = [s.qx[i], s.qy[i], s.qz[i], s.qw[i]];
        let sign = if qi[3] < 0.0 { -1.0 } else { 1.0 };
        for (a, b) in q.iter_mut().zip(qi) {
            *a += sign * b;
        }
    }
    let r = Quat::from_xyzw(q[0], q[1], q[2], q[3]).normalize();
    let (lo, hi) = (min + 0.5 * d, max - 0.5 * d);
    let f = &sim.fluid;
    (0..f.len())
        .filter(|&i| {
            let p = r.inverse() * (Vec3::new(f.x[i], f.y[i], f.z[i]) - c) + c0;
            p.cmpgt(lo).all() && p.cmplt(hi).all()
        })
        .count()
}

/// A block of density 700 kg/m^3 dropped from 10 cm above the water of a
/// closed tank: it enters at about 1.4 m/s, plunges and comes back up. For
/// 5 s no fluid particle may get inside it (checked every 0.05 s) and the
/// run must stay stable (no step error, the block ends afloat).
#[test]
fn dropped_block_keeps_the_fluid_out_and_stays_stable() {
    let d = 0.01f32;
    let (min, max) = (Vec3::new(0.15, 0.3, 0.04), Vec3::new(0.25, 0.36, 0.12));
    let scene = TankWithBlock {
        d,
        tank: [0.4, 0.5, 0.16],
        water: 0.2,
        viscosity: 0.01,
        lo: min.to_array(),
        hi: max.to_array(),
        density: 700.0,
        lambda: 5e4,
    }
    .text();
    let mut sim = Simulation::new(common::scene_text(&scene));
    let mut next = 0.0;
    let (mut worst, mut checks, mut lowest, mut max_cg) = (0, 0, f32::MAX, 0);
    while sim.time < 5.0 {
        let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
        max_cg = max_cg.max(st.cg_iterations);
        if sim.time >= next {
            worst = worst.max(fluid_inside(&sim, min, max, d));
            checks += 1;
            next += 0.05;
            lowest = lowest.min(sim.solids.y.iter().copied().fold(f32::MAX, f32::min));
        }
    }
    let bottom = sim.solids.y.iter().copied().fold(f32::MAX, f32::min);
    println!(
        "dropped block: {} fluid + {} solid particles, {} steps to 5 s, {checks} checks, most fluid particles inside {worst}, \
         lowest point {lowest:.3} m, final bottom {bottom:.3} m, max CG iterations {max_cg}",
        sim.fluid.len(),
        sim.solids.len(),
        sim.step
    );
    assert_eq!(worst, 0, "fluid got inside the block");
    assert!(bottom > 0.1, "the block did not float back up (bottom at {bottom} m)");
}

/// `elastic_prediction_tolerance`: the prediction of the solids only
/// estimates where they go for the pressure solve; the step's last response
/// also solves what the prediction left, so that the new velocities solve
/// the implicit elastic step to `elastic_tolerance` whatever the
/// prediction's tolerance. What a looser prediction still changes is the
/// pressure solve's estimate, so the pressures. The block of the
/// dropped-block test (700 kg/m^3) through its fall and its entry into the
/// water at about 1.4 m/s, 0.3 s. Reference: the same run with both elastic
/// solves to 1e-6 (the implicit step nearly exact). Asked: with the
/// defaults (prediction 1e-2, responses 1e-4) every solid particle is
/// closer to the reference than halving the pressure solve's own tolerance
/// (max_density_error 1e-3 -> 5e-4) moves it, and the step's CG residual
/// (`cg_residual`) stays within `elastic_tolerance`. Measured 2026-12-06:
/// 1.24e-2 d against 3.22e-2 d (the prediction at 1e-4: 8.10e-4 d), 2,035
/// CG iterations against 3,037 with the prediction at 1e-4 (4,369 before
/// the last response took on the prediction's residual).
#[test]
fn a_loose_prediction_leaves_the_elastic_step_to_the_last_response() {
    let d = 0.01f32;
    let scene = |pred: f32, tol: f32, eta: f32| {
        let text = TankWithBlock {
            d,
            tank: [0.4, 0.5, 0.16],
            water: 0.2,
            viscosity: 0.01,
            lo: [0.15, 0.3, 0.04],
            hi: [0.25, 0.36, 0.12],
            density: 700.0,
            lambda: 5e4,
        }
        .text();
        let keys = format!(
            "[simulation]\nelastic_prediction_tolerance = {pred}\nelastic_tolerance = {tol}\nmax_density_error = {eta}\n"
        );
        text.replace("[simulation]\n", &keys)
    };
    let run = |pred: f32, tol: f32, eta: f32| {
        let mut sim = Simulation::new(common::scene_text(&scene(pred, tol, eta)));
        let (mut cg, mut worst_residual) = (0u64, 0.0f32);
        while sim.time < 0.3 {
            let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
            cg += u64::from(st.cg_iterations);
            worst_residual = worst_residual.max(st.cg_residual);
        }
        (sim, cg, worst_residual)
    };
    let (exact, _, _) = run(1e-6, 1e-6, 1e-3);
    let (half_eta, _, _) = run(1e-6, 1e-6, 5e-4);
    let (tight, cg_tight, _) = run(1e-4, 1e-4, 1e-3);
    let (loose, cg_loose, residual) = run(1e-2, 1e-4, 1e-3);
    let off = |sim: &Simulation| {
        assert_eq!(sim.step, exact.step, "the same steps");
        let (a, b) = (&exact.solids, &sim.solids);
        (0..a.len())
            .map(|i| Vec3::new(a.x[i] - b.x[i], a.y[i] - b.y[i], a.z[i] - b.z[i]).length())
            .fold(0.0f32, f32::max)
    };
    let (band, off_tight, off_loose) = (off(&half_eta), off(&tight), off(&loose));
    let s = &exact.solids;
    let fall = (s.y0.iter().sum::<f32>() - s.y.iter().sum::<f32>()) / s.len() as f32;
    println!(
        "{} steps to 0.3 s, the block fell {fall:.3} m. Largest distance from the reference: max_density_error 5e-4 \
         {:.2e} d; prediction 1e-4 {:.2e} d, 1e-2 {:.2e} d; CG iterations {cg_tight} / {cg_loose}; largest residual \
         {residual:.1e}",
        exact.step,
        band / d,
        off_tight / d,
        off_loose / d
    );
    assert!(fall > 0.1, "the block entered the water");
    assert!(off_loose <= band, "{off_loose} m from the reference against the pressure tolerance's {band} m");
    assert!(residual <= 1e-4, "residual {residual}");
}

/// One fluid layer between the floor and a fixed block (the block one
/// spacing above the floor): the relaxed Jacobi loop had an oscillating
/// mode there (wall and solid pressures rising in turn) that grew at the
/// default omega = 0.5 and blew step 1 up (velocity 4e11 m/s); the loop
/// detects such growth (`iisph::Divergence`) and starts over with a
/// smaller omega. Since the solid rows count the body's own share of their
/// neighbourhood from the rest lattice (`volumes::own_occupancy`), which no
/// longer over-counts the block's edges and corners, the mode does not
/// appear here (measured: 2 sweeps and no restart in step 1). Reference:
/// the solver's own convergence criterion, the mean density error <=
/// max_density_error (1e-3), at every step of 0.2 s, without a restart
/// budget overrun or a step error.
#[test]
fn one_fluid_layer_under_a_block_converges_at_the_default_omega() {
    // The block held (`fixed`), dt 2 ms.
    let block = TankWithBlock {
        d: 0.02,
        tank: [0.3, 0.3, 0.1],
        water: 0.15,
        viscosity: 1.0,
        lo: [0.1, 0.02, 0.0],
        hi: [0.2, 0.12, 0.1],
        density: 600.0,
        lambda: 1e4,
    };
    let scene = block.text().replace("max_dt = 0.003", "max_dt = 0.002")
        + "fixed = { box = { min = [0.1, 0.02, 0.0], max = [0.2, 0.12, 0.1] } }\n";
    let mut sim = Simulation::new(common::scene_text(&scene));
    let (mut restarts, mut worst) = (0, 0.0f32);
    for step in 1..=100 {
        let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
        restarts += st.solve_restarts;
        worst = worst.max(st.density_error);
        if step == 1 {
            println!(
                "step 1: {} sweeps, {} restart(s), density error {:.2e}",
                st.iterations, st.solve_restarts, st.density_error
            );
        }
        assert!(st.density_error <= 1e-3, "step {step}: density error {}", st.density_error);
    }
    println!("100 steps: {restarts} restart(s) in all, worst density error {worst:.2e}");
}

/// Two porous blocks stacked so that they touch (the upper one's bottom
/// layer one spacing above the lower one's top layer), both held, in a tank
/// of water. A solid row used to count the other body's particles in its
/// sigma, so it was compressed by a neighbour the fluid cannot push away,
/// and its pressure grew as 1/diag where one fluid particle barely reached
/// it: 5e9 Pa and a blow-up at step 1 here (Example 5's layers had to be set
/// 2 cm apart). Now a solid row's own-body share comes from the rest
/// lattice and another body counts like a wall; these two blocks are both
/// held, so their particles are not pressure pairs at all (nothing could
/// move them apart; `porosph_kernels::solid_rows`). References: the solver's convergence
/// criterion (mean density error <= 1e-3) at every step; mass conservation
/// of the water (outer + inner, <= 1e-6, as tests/porous.rs); and the
/// largest solid-row pressure against the same tank with the lower block
/// alone (no contact), which sets the level this set-up reaches anyway (the
/// first steps' start-up transient included): at most 1.5x that. Measured
/// (2026-11-22): see the printed line.
#[test]
fn touching_porous_blocks_keep_the_pressures_of_a_lone_block() {
    let block = |name: &str, y0: f32| {
        format!(
            "[[solid]]\nname = \"{name}\"\nbox = {{ min = [0.1, {y0}, 0.0], max = [0.3, {y1}, 0.1] }}\n\
             density = 600.0\nshear_modulus = 2e4\nlame_lambda = 1e4\n\
             fixed = {{ box = {{ min = [0.1, {y0}, 0.0], max = [0.3, {y1}, 0.1] }} }}\n\
             [solid.porous]\nporosity = 0.6\nrest_pore_pressure = 5e4\nbiot_modulus = 4.9e4\n\
             capillarity = 2.0\nabsorption = 1.0\n\
             [solid.porous.phase.water]\npermeability = 1e-7\nouter_pore_pressure = 2.5e4\n",
            y1 = y0 + 0.1
        )
    };
    let tank = "[simulation]\nparticle_spacing = 0.02\nend_time = 2.0\nmax_dt = 0.002\n\
         [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 1.0\n\
         [[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.4, 0.4, 0.1] }\ncontainer = true\n\
         [[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.4, 0.3, 0.1] }\nfractions = { water = 1.0 }\n";
    // (largest solid-row pressure, water mass drift, inner volume) over 300 steps.
    let run = |scene: String| {
        let mut sim = Simulation::new(common::scene_text(&scene));
        let m0 = sim.phase_masses()[0];
        let (mut worst_p, mut worst_mass) = (0.0f32, 0.0f64);
        for step in 1..=300 {
            let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
            assert!(st.density_error <= 1e-3, "step {step}: density error {}", st.density_error);
            worst_p = sim.solids.pressure.iter().fold(worst_p, |m, &p| m.max(p));
            worst_mass = worst_mass.max(((sim.phase_masses()[0] - m0) / m0).abs());
        }
        (worst_p, worst_mass, sim.phase_volumes_split().1[0])
    };
    let lone = run(format!("{tank}{}", block("lower", 0.0)));
    let two = run(format!("{tank}{}{}", block("lower", 0.0), block("upper", 0.1)));
    println!(
        "300 steps: largest solid-row pressure {:.3e} Pa touching vs {:.3e} Pa lone; water mass drift {:.1e} / {:.1e}; \
         inner volume {:.3e} / {:.3e} m^3",
        two.0, lone.0, two.1, lone.1, two.2, lone.2
    );
    assert!(two.2 > 0.0, "nothing absorbed");
    assert!(two.1 <= 1e-6, "mass drift {:e}", two.1);
    assert!(two.0 <= 1.5 * lone.0, "solid-row pressure {} Pa vs {} Pa without contact", two.0, lone.0);
}
