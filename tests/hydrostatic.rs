//! Hydrostatic tank at rest (core issue): after 1 s, the IISPH pressure
//! equals rho g depth and the fluid is incompressible to 0.1 %.
//!
//! Reference: hydrostatics, p = rho |g| (y_s - y) with the free surface y_s
//! at the top of the initial fluid block (the fill height; the column is
//! incompressible to 0.1 %, so y_s moves by well under a particle spacing).

mod common;

use porosph::pipeline::Simulation;

#[test]
fn pressure_is_rho_g_depth_after_one_second() {
    let scene = common::scene_file("hydrostatic.toml");
    let fill = 0.3f32; // fluid block top in scenes/hydrostatic.toml
    let rho0 = scene.phases[0].density;
    let g = -scene.simulation.gravity[1];
    let d = scene.simulation.particle_spacing;
    let mut sim = Simulation::new(scene);
    common::run_until(&mut sim, 1.0);

    let f = &sim.fluid;
    // Particles below the top two layers of the fill.
    let deep: Vec<usize> = (0..f.len()).filter(|&i| f.y[i] < fill - 2.0 * d).collect();
    assert!(deep.len() > f.len() / 2);
    let (mut sp, mut sref, mut sabs, mut sdens) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for &i in &deep {
        let p_ref = (rho0 * g * (fill - f.y[i])) as f64;
        sp += f.pressure[i] as f64;
        sref += p_ref;
        sabs += (f.pressure[i] as f64 - p_ref).abs();
        sdens += (f.density[i] / rho0 - 1.0).abs() as f64;
    }
    let n = deep.len() as f64;
    let mean_err = (sp - sref).abs() / sref;
    let mean_abs_err = sabs / sref;
    let density_err = sdens / n;
    println!(
        "hydrostatic: {} particles below the top two layers; mean pressure {:.1} Pa vs rho g depth {:.1} Pa: \
         relative error of the mean {:.4}, mean absolute error / mean reference {:.4}; mean |rho/rho0 - 1| = {:.5}; \
         solver: {} iterations, predicted error {:.5}; max speed {:.2e} m/s",
        deep.len(),
        sp / n,
        sref / n,
        mean_err,
        mean_abs_err,
        density_err,
        sim.last.iterations,
        sim.last.density_error,
        sim.last.max_speed
    );
    assert!(mean_err < 0.02, "mean pressure off by {:.2} %", 100.0 * mean_err);
    assert!(density_err <= 0.001, "mean density error {:.4} %", 100.0 * density_err);
}
