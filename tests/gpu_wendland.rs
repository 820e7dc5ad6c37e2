//! Scenes with `kernel = "wendland_c2"` run on the GPU and on the CPU
//! (issue 37): the GPU passes take the scene's kernel, so they agree as the
//! cubic spline's runs do (tests/gpu_dam_break.rs, tests/gpu_mixture.rs),
//! within the same bounds. The symptom this guards against: the GPU passes
//! recomputed g_ij with the cubic spline's gradient whatever the scene
//! said, so the pressure solve and the drift mixed Wendland rows from the
//! CPU with spline gradients, silently.
//!
//! Tolerances are those of the spline's tests, for the same reasons: the
//! two backends differ by f32 rounding (summation order, the GPU's
//! recomputed g_ij), which the flow carries forward slowly. Measured on
//! lavapipe (2026-12-05): dam break positions 4.1e-4 h apart after 50
//! steps, mean density errors equal to 4 digits, 403 iterations on both;
//! two-phase run: largest drift speed 3.2e-6 apart, oil fraction per
//! particle 1.3e-5, phase volumes 2e-11. With the spline's gradient on the
//! GPU (before the fix): positions 2.0 h apart, iterations 403 vs 411;
//! drift speed 7.9e-2 apart, oil fraction 6.3e-3.

mod common;
mod gpu_common;

use porosph::backend::GpuPasses;
use porosph::pipeline::Simulation;
use std::collections::HashMap;

/// `text` with `kernel = "wendland_c2"` in its `[simulation]` table.
fn wendland(text: &str) -> porosph::scene::Scene {
    let text = text.replacen("[simulation]\n", "[simulation]\nkernel = \"wendland_c2\"\n", 1);
    assert!(text.contains("wendland_c2"), "no [simulation] table");
    common::scene_text(&text)
}

/// Positions by particle id.
fn positions(sim: &Simulation) -> HashMap<u32, [f32; 3]> {
    let f = &sim.fluid;
    (0..f.len()).map(|i| (f.id[i], [f.x[i], f.y[i], f.z[i]])).collect()
}

/// The Wendland dam break, 50 steps with every GPU pass (sort, cell-range
/// tables, pressure solve) on the device and on the CPU. Bounds of
/// tests/gpu_dam_break.rs: mean density error within 10 %, positions after
/// 50 steps within 3e-3 h.
#[test]
fn wendland_dam_break_on_gpu_matches_cpu() {
    const H: f32 = 0.01;
    let Some(gpu) = gpu_common::backend(GpuPasses::ALL) else { return };
    let go = |mut sim: Simulation| {
        let (mut err, mut iterations) = (0.0f64, 0u64);
        for _ in 0..50 {
            let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
            err += f64::from(st.density_error);
            iterations += u64::from(st.iterations);
        }
        (positions(&sim), err / 50.0, iterations)
    };
    let cpu = go(Simulation::new(wendland(common::SMALL_DAM_BREAK)));
    let mut sim = Simulation::new(wendland(common::SMALL_DAM_BREAK));
    sim.use_gpu(gpu);
    let g = go(sim);
    assert_eq!(g.0.len(), cpu.0.len());
    let rel = (g.1 - cpu.1).abs() / cpu.1;
    let dx = cpu
        .0
        .iter()
        .map(|(id, a)| {
            let b = g.0[id];
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        })
        .fold(0.0f32, f32::max);
    eprintln!(
        "{} particles; mean density error cpu {:.4e} gpu {:.4e} ({:.2} % apart); iterations cpu {} gpu {}; \
         max position difference after 50 steps {:.3e} m = {:.2e} h",
        cpu.0.len(),
        cpu.1,
        g.1,
        100.0 * rel,
        cpu.2,
        g.2,
        dx,
        dx / H
    );
    assert!(rel <= 0.10, "mean density error {} (gpu) vs {} (cpu)", g.1, cpu.1);
    assert!(dx <= 3e-3 * H, "positions after 50 steps differ by {dx} m = {} h", dx / H);
}

/// The two-phase dam break of `tests/common` with Wendland, 100 steps with
/// the drift velocities on the GPU and on the CPU. Bounds of
/// tests/gpu_mixture.rs: phase volumes 1e-4 relative, largest drift speed
/// 1 %, oil fraction per particle 2e-3.
#[test]
fn wendland_two_phase_run_with_gpu_drift_matches_cpu() {
    let passes = GpuPasses { neighbors: false, pressure_solve: false, drift: true };
    let Some(gpu) = gpu_common::backend(passes) else { return };
    let go = |mut sim: Simulation| {
        let mut max_drift = 0.0;
        for _ in 0..100 {
            max_drift = sim.step().unwrap_or_else(|e| panic!("{e}")).max_drift_speed;
        }
        let f = &sim.fluid;
        let oil: HashMap<u32, f32> = (0..f.len()).map(|i| (f.id[i], f.alpha[1][i])).collect();
        (sim.phase_volumes(), max_drift, oil)
    };
    let cpu = go(Simulation::new(wendland(common::TWO_PHASE)));
    let mut sim = Simulation::new(wendland(common::TWO_PHASE));
    sim.use_gpu(gpu);
    let g = go(sim);
    assert_eq!(g.2.len(), cpu.2.len());
    assert!(cpu.1 > 0.0, "the scene has no drift");
    let dv = g.0.iter().zip(&cpu.0).map(|(a, b)| (a - b).abs() / b).fold(0.0f64, f64::max);
    let dd = (g.1 - cpu.1).abs() / cpu.1;
    let da = cpu.2.iter().map(|(id, a)| (a - g.2[id]).abs()).fold(0.0f32, f32::max);
    eprintln!(
        "{} particles; phase volumes cpu {:?} gpu {:?} ({dv:.2e} apart); max drift speed cpu {:e} gpu {:e} \
         ({dd:.2e} apart); max oil fraction difference per particle {da:.2e}",
        cpu.2.len(),
        cpu.0,
        g.0,
        cpu.1,
        g.1
    );
    assert!(dv <= 1e-4, "phase volumes gpu {:?} cpu {:?}", g.0, cpu.0);
    assert!(dd <= 0.01, "max drift speed gpu {} cpu {}", g.1, cpu.1);
    assert!(da <= 2e-3, "oil fractions differ by {da}");
}
