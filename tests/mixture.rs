//! The mixture model (issue 3; PHYSICS.md §4.1): fractions stay a partition
//! of unity, phase volumes are conserved, a suspension settles at the speed
//! its drift formula gives, and heavy fluid over light fluid overturns.
//!
//! Every scene here is coarse (stated per test) to keep the file fast.
//! Numbers these tests print are quoted in the issue's closing note.

mod common;

use porosph::pipeline::Simulation;
use porosph_kernels::kernel::Kernel;

/// Largest |sum_k alpha_k - 1| and smallest alpha over the fluid.
fn fraction_errors(sim: &Simulation) -> (f32, f32) {
    let f = &sim.fluid;
    let (mut dev, mut low) = (0.0f32, f32::INFINITY);
    for i in 0..f.len() {
        let s: f32 = f.alpha.iter().map(|a| a[i]).sum();
        dev = dev.max((s - 1.0).abs());
        low = low.min(f.alpha.iter().map(|a| a[i]).fold(f32::INFINITY, f32::min));
    }
    (dev, low)
}

/// Largest relative change of a phase volume from `v0`.
fn volume_drift(sim: &Simulation, v0: &[f64]) -> f64 {
    sim.phase_volumes().iter().zip(v0).map(|(v, v0)| ((v - v0) / v0).abs()).fold(0.0, f64::max)
}

/// `scenes/two_phase_mixing.toml` (a brine column collapsing into a water
/// pool) at twice its particle spacing, 0.02 m: about 1.3k particles.
fn coarse_mixing(extra: &str) -> Simulation {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/two_phase_mixing.toml");
    let text = std::fs::read_to_string(path).expect("scene file");
    let text = text.replacen("particle_spacing = 0.01 ", "particle_spacing = 0.02 ", 1);
    let text = text.replacen("[simulation]\n", &format!("[simulation]\n{extra}\n"), 1);
    Simulation::new(common::scene_text(&text))
}

/// The issue's checks on a mixing scene: after every step the fractions of
/// every particle lie in [0, 1] and sum to 1 (to float rounding: 1e-6 for
/// f32 sums of a few terms), and each phase's volume sum_i h^3 alpha_k is
/// conserved. The issue's target is 0.1 % over 2000 steps; the default
/// (conservative) transport conserves it to rounding, so the test asserts
/// 1e-9 over 600 steps (at 0.02 m). Measured 2.1e-11: what is left is the
/// f32 rounding of each particle's sum of pair fluxes, random in sign. With
/// the fractions stored in f32 alone it was 2e-8, a bias: a pure particle
/// keeps alpha = 1 when it loses less than half an ulp
/// (`porosph_kernels::phases::join`). The reference form of
/// P-Eq. 2 (PHYSICS.md §4.1 as written) is run too and its drift printed,
/// for comparison.
#[test]
fn fractions_sum_to_one_and_phase_volumes_are_conserved() {
    let mut sim = coarse_mixing("");
    let v0 = sim.phase_volumes();
    let mut mixed = 0;
    for _ in 0..600 {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        let (dev, low) = fraction_errors(&sim);
        assert!(dev <= 1e-6, "step {}: |sum alpha - 1| = {dev:e}", sim.step);
        assert!(low >= 0.0, "step {}: alpha = {low:e} < 0", sim.step);
        let f = &sim.fluid;
        mixed = (0..f.len()).filter(|&i| f.alpha[1][i] > 0.01 && f.alpha[1][i] < 0.99).count();
    }
    let drift = volume_drift(&sim, &v0);
    let mut reference = coarse_mixing("phase_transport = \"reference\"");
    let v0_reference = reference.phase_volumes();
    for _ in 0..600 {
        reference.step().unwrap_or_else(|e| panic!("{e}"));
    }
    println!(
        "mixing, 0.02 m, 600 steps (t = {:.3} s): {} particles, {} of them mixed; phase volume drift: \
         conservative {:.2e}, reference form {:.2e}",
        sim.time,
        sim.fluid.len(),
        mixed,
        drift,
        volume_drift(&reference, &v0_reference),
    );
    assert!(mixed > sim.fluid.len() / 10, "the phases do not mix: {mixed} mixed particles");
    assert!(drift <= 1e-9, "phase volume drift {drift:e}");
}

/// A suspension of `heavy` (1500 kg/m^3) in `light` (1000 kg/m^3) with
/// heavy fraction `alpha0`, 0.16 m deep in a closed box 0.1 x 0.2 x 0.04 m,
/// particle spacing 0.01 m (10 x 16 x 4 = 640 particles).
fn suspension(alpha0: f64, tau: f64, extra: &str) -> Simulation {
    let text = format!(
        r#"
[simulation]
particle_spacing = 0.01
end_time = 10.0
max_dt = 0.002
drift_tau = {tau}
drift_sigma = 0.0
drift_momentum = "off"
{extra}

[[phase]]
name = "light"
density = 1000.0
viscosity = 0.01

[[phase]]
name = "heavy"
density = 1500.0
viscosity = 0.01

[[fluid]]
box = {{ min = [0.0, 0.0, 0.0], max = [0.1, 0.16, 0.04] }}
fractions = {{ light = {}, heavy = {alpha0} }}

[[wall]]
box = {{ min = [0.0, 0.0, 0.0], max = [0.1, 0.2, 0.04] }}
container = true
"#,
        1.0 - alpha0
    );
    Simulation::new(common::scene_text(&text))
}

/// kappa, the rate at which the symmetric pair flux sum_j (F_i + F_j) . g_ij
/// of the transport moves a uniform vertical flux F across a horizontal
/// plane, per unit area, over |F|, on the lattice of `suspension`: nx x nz
/// columns of spacing d, H = 2d, Vbar = d^3, fluid pairs only (so columns
/// next to a side wall lack the pairs across it). By the same sum it is also
/// the factor by which the difference-form gradient
/// sum_j Vbar (A_j - A_i) grad W_ij sees a vertical gradient of A. The
/// continuum value is 1, an unbounded lattice gives 1.0201, this narrow box
/// 0.913.
fn cross_plane_factor(nx: i32, nz: i32) -> f64 {
    let kernel = Kernel::new(2.0);
    let mut sum = 0.0f64;
    for ix in 0..nx {
        for iz in 0..nz {
            for a in -3i32..=3 {
                for b in -3i32..=3 {
                    if !(0..nx).contains(&(ix + a)) || !(0..nz).contains(&(iz + b)) {
                        continue;
                    }
                    // Pairs i (layer m >= 0 above the plane), j (layer n >= 0
                    // below) at vertical offset c = m + n + 1: c of them per
                    // c; F_i and F_j both count; |g_y| = (-W'(r)/r) c.
                    for c in 1i32..=3 {
                        let r = ((a * a + b * b + c * c) as f32).sqrt();
                        sum += 2.0 * f64::from(c * c) * f64::from(-kernel.grad_over_r(r));
                    }
                }
            }
        }
    }
    sum / f64::from(nx * nz)
}

/// Initial settling speed of the top of a two-phase suspension, m/s, as
/// the test measures it: the heavy volume in the particles that start above
/// y = 0.12 m (the top four layers) falls at rate alpha0 s A (A = 0.004 m^2,
/// the box's floor) while the clear layer grows from the top and nothing
/// from the bottom has arrived; s is fitted over t = 0.04-0.24 s, after the
/// pressure has settled in the first steps. The particles barely move (the
/// box is closed and full below the surface), so membership by start
/// position is by particle id.
fn settling_speed(sim: &mut Simulation, alpha0: f64) -> f64 {
    let f = &sim.fluid;
    let start_y: Vec<f32> = {
        let mut y = vec![0.0; f.len()];
        for i in 0..f.len() {
            y[f.id[i] as usize] = f.y[i];
        }
        y
    };
    let heavy_above = |sim: &Simulation| -> f64 {
        let f = &sim.fluid;
        let h3 = f64::from(sim.params.cell_volume());
        (0..f.len()).filter(|&i| start_y[f.id[i] as usize] > 0.12).map(|i| h3 * f64::from(f.alpha[1][i])).sum()
    };
    let mut samples = Vec::new();
    while sim.time < 0.24 - 1e-9 {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        if sim.time >= 0.04 - 1e-9 {
            samples.push((sim.time, heavy_above(sim)));
        }
    }
    // Least-squares slope.
    let n = samples.len() as f64;
    let (mt, mv) = (samples.iter().map(|s| s.0).sum::<f64>() / n, samples.iter().map(|s| s.1).sum::<f64>() / n);
    let num: f64 = samples.iter().map(|s| (s.0 - mt) * (s.1 - mv)).sum();
    let den: f64 = samples.iter().map(|s| (s.0 - mt) * (s.0 - mt)).sum();
    -(num / den) / (alpha0 * 0.1 * 0.04)
}

/// Sedimentation (issue 3): the initial settling speed of the mixture top.
///
/// Reference, derived for this drift formula (P-Eq. 11, PHYSICS.md §4.1;
/// tau not divided by the viscosity). In a column at rest a = g and
/// grad p = rho_m g, so for two phases h, l with uniform fractions
/// u_mh - u_ml = v_h - v_l = tau [(rho_h - rho_l) g - (grad p_h - grad p_l)]
/// = tau g [(rho_h - rho_l) - phi rho_m (alpha_h - alpha_l)], with phi = 0
/// for the shared phase pressure (the default, p_k = p) and phi = 1 for
/// fraction pressures (p_k = alphahat_k p, grad p_k = alpha_k grad p). The
/// transport moves the heavy phase at F_h = alpha_h alpha_l (u_mh - u_ml),
/// so the top of the suspension (clear light fluid above it) falls at
///
/// s = F_h / alpha_h = tau |g| alpha_l [(rho_h - rho_l) - phi rho_m (alpha_h - alpha_l)]
///
/// (also the continuum value, for incompressible phases). With the shared
/// pressure, or at alpha0 = 0.5, it is exactly the issue's
/// tau (1 - alpha0)(rho_h - rho_l)|g|. Discretely, the pair sums move a
/// flux across a plane, and see a vertical pressure gradient, at kappa
/// times its value ([`cross_plane_factor`], 0.913 in this narrow box), so
/// the measured s is compared with
/// kappa tau |g| alpha_l [(rho_h - rho_l) - phi kappa rho_m (alpha_h - alpha_l)]
/// within 3 %, and with the issue's form, where it applies, within 20 %.
/// Densities 1500 / 1000 kg/m^3, tau = 8e-6 m^2/(Pa s), sigma = 0.
#[test]
fn suspension_top_settles_at_the_drift_speed() {
    let (g, rho_h, rho_l, tau) = (9.81f64, 1500.0f64, 1000.0f64, 8e-6f64);
    let kappa = cross_plane_factor(10, 4);
    for (alpha0, extra, phi) in [(0.5, "", 0.0), (0.3, "", 0.0), (0.3, "phase_pressure = \"fraction\"", 1.0)] {
        let mut sim = suspension(alpha0, tau, extra);
        let s = settling_speed(&mut sim, alpha0);
        let alpha_l = 1.0 - alpha0;
        let rho_m = alpha0 * rho_h + alpha_l * rho_l;
        let exact = tau * g * alpha_l * ((rho_h - rho_l) - phi * rho_m * (alpha0 - alpha_l));
        let discrete = kappa * tau * g * alpha_l * ((rho_h - rho_l) - phi * kappa * rho_m * (alpha0 - alpha_l));
        let approx = tau * alpha_l * (rho_h - rho_l) * g;
        println!(
            "alpha0 = {alpha0}, {} pressure: settling speed {s:.5} m/s; exact {exact:.5} ({:+.1} %), on this lattice \
             {discrete:.5} ({:+.1} %, kappa {kappa:.4}); issue's form {approx:.5} ({:+.1} %)",
            if phi > 0.0 { "fraction" } else { "shared" },
            100.0 * (s / exact - 1.0),
            100.0 * (s / discrete - 1.0),
            100.0 * (s / approx - 1.0)
        );
        assert!((s / discrete - 1.0).abs() < 0.03);
        if alpha0 == 0.5 || phi == 0.0 {
            assert!((s / approx - 1.0).abs() < 0.2);
        }
    }
}

/// Sedimentation runs to the end: a uniform suspension (alpha0 = 0.5)
/// separates, the heavy phase at the bottom and clear light fluid on top.
/// tau = 4e-5 m^2/(Pa s), so that settling takes about 1.5 s; checked at
/// 3 s. With fraction phase pressures the settling stops where the drift
/// vanishes, (rho_h - rho_l) = rho_m (2 alpha_h - 1), i.e. alpha_h = 0.69
/// for these densities (`porosph_kernels::drift`); the test checks that
/// too.
#[test]
fn suspension_separates_with_the_heavy_phase_at_the_bottom() {
    for (extra, bottom_min, bottom_max) in [("", 0.95, 1.0), ("phase_pressure = \"fraction\"", 0.6, 0.75)] {
        let mut sim = suspension(0.5, 4e-5, extra);
        common::run_until(&mut sim, 3.0);
        let f = &sim.fluid;
        let layer = |lo: f32, hi: f32| -> f64 {
            let sel: Vec<usize> = (0..f.len()).filter(|&i| f.y[i] >= lo && f.y[i] < hi).collect();
            sel.iter().map(|&i| f64::from(f.alpha[1][i])).sum::<f64>() / sel.len() as f64
        };
        let (bottom, top) = (layer(0.0, 0.04), layer(0.12, 0.2));
        println!(
            "{} pressure, t = 3 s: heavy fraction {bottom:.3} in the bottom 4 layers, {top:.3} in the top 4",
            if extra.is_empty() { "shared" } else { "fraction" }
        );
        assert!((bottom_min..=bottom_max).contains(&bottom), "bottom {bottom}");
        assert!(top < 0.2 && top < bottom - 0.4, "top {top}");
    }
}

/// Rayleigh-Taylor: heavy fluid (1500 kg/m^3) over light (1000 kg/m^3)
/// filling a closed box 0.2 x 0.4 x 0.02 m, spacing 0.01 m (1.6k particles,
/// two layers deep), the interface at y = 0.2 m lowered by 0.03 m over the
/// left half (the perturbation); sigma = 1e-4 m^2/s so that diffusion
/// (about 2 cm in 3 s) does not blur the layers first. The heavy fluid
/// falls along the left wall as a plume while the light rises beside it;
/// the centres of mass cross at about t = 2.2 s. After 3 s the heavy
/// phase's centre of mass must lie 2 cm below the light phase's (at the
/// start it is 0.2 m above).
#[test]
fn rayleigh_taylor_heavy_over_light_inverts() {
    rayleigh_taylor("");
}

/// The same with `pressure_warm_start = "hydrostatic"`. Its estimate took
/// each particle's own density for the whole column above it (1000 g
/// depth for the light fluid under 0.2 m of heavy, whose weight is 1500 g
/// 0.2), so every solve began with a pressure step at the interface: the
/// largest speed was 0.17 m/s after the first step (0.020 with the plain
/// half warm start), 0.9 m/s by step 55, and the run blew up at step 74 (a
/// particle at 3.7e6 m/s). The estimate is now the column's weight
/// (`porosph_kernels::hydrostatic`); the reference is the plain run's
/// (above): the heavy phase's centre of mass 2 cm below the light's at 3 s.
#[test]
fn rayleigh_taylor_with_the_hydrostatic_warm_start_inverts() {
    rayleigh_taylor("pressure_warm_start = \"hydrostatic\"\n");
}

fn rayleigh_taylor(options: &str) {
    let text = r#"
[simulation]
particle_spacing = 0.01
end_time = 10.0
max_dt = 0.002
drift_sigma = 1e-4

[[phase]]
name = "light"
density = 1000.0
viscosity = 0.01

[[phase]]
name = "heavy"
density = 1500.0
viscosity = 0.01

[[fluid]]
box = { min = [0.0, 0.17, 0.0], max = [0.1, 0.4, 0.02] }
fractions = { heavy = 1.0 }

[[fluid]]
box = { min = [0.1, 0.2, 0.0], max = [0.2, 0.4, 0.02] }
fractions = { heavy = 1.0 }

[[fluid]]
box = { min = [0.0, 0.0, 0.0], max = [0.2, 0.2, 0.02] }
fractions = { light = 1.0 }

[[wall]]
box = { min = [0.0, 0.0, 0.0], max = [0.2, 0.4, 0.02] }
container = true
"#
    .replace("drift_sigma = 1e-4\n", &format!("drift_sigma = 1e-4\n{options}"));
    let mut sim = Simulation::new(common::scene_text(&text));
    let centre = |sim: &Simulation, k: usize| -> f64 {
        let f = &sim.fluid;
        let m: f64 = f.alpha[k].iter().map(|&a| f64::from(a)).sum();
        (0..f.len()).map(|i| f64::from(f.alpha[k][i]) * f64::from(f.y[i])).sum::<f64>() / m
    };
    let (l0, h0) = (centre(&sim, 0), centre(&sim, 1));
    common::run_until(&mut sim, 3.0);
    let (l1, h1) = (centre(&sim, 0), centre(&sim, 1));
    println!(
        "Rayleigh-Taylor ({} particles, {} steps): centre of mass of heavy / light {h0:.3} / {l0:.3} m at t = 0, \
         {h1:.3} / {l1:.3} m at t = {:.2} s",
        sim.fluid.len(),
        sim.step,
        sim.time
    );
    assert!(h0 > l0 + 0.15);
    assert!(h1 < l1 - 0.02, "the heavy fluid stayed on top");
}

/// "A one-phase scene gives the same result as before this issue": with
/// one phase the step skips the mixture passes (drift, drift momentum,
/// transport, correction) and runs the single-fluid passes unchanged, so
/// it is the pre-issue step by construction (and its state hash after 60
/// steps of the dam break, printed by tests/determinism.rs, is the one of
/// the commit before this issue, e195569fc804adf9). This test checks the
/// other half: the mixture path itself reduces to the one-phase step. The
/// dam break (16k particles, 60 steps) with a second phase that is absent
/// everywhere and drift_tau = 0 runs every mixture pass (the phase pair
/// weights, drift velocities, the drift momentum term, the conservative
/// transport with its limiter, the correction, the drift time step terms),
/// and every common array must come out equal, number for number, to the
/// one-phase run's. (Equal as numbers: a zero's sign may differ, which
/// no later arithmetic can turn into a different nonzero value.)
#[test]
fn one_phase_scene_is_unchanged_by_the_mixture_passes() {
    let one = common::scene_file("dam_break.toml");
    let two =
        format!("{}\n[[phase]]\nname = \"absent\"\ndensity = 3000.0\nviscosity = 1.0\ndrift_tau = 0.0\n", one.text);
    let two = common::scene_text(&two);
    assert_eq!(two.phases.len(), 2);
    let run = |scene| {
        let mut sim = Simulation::new(scene);
        for _ in 0..60 {
            sim.step().unwrap_or_else(|e| panic!("{e}"));
        }
        sim
    };
    let (a, b) = (run(one), run(two));
    assert_eq!(a.time.to_bits(), b.time.to_bits(), "the time steps differ");
    let (fa, fb) = (&a.fluid, &b.fluid);
    let same = |name: &str, x: &[f32], y: &[f32]| {
        let bad = x.iter().zip(y).position(|(p, q)| p != q);
        assert!(bad.is_none(), "{name} differs at particle {bad:?}");
    };
    for (name, x, y) in [
        ("x", &fa.x, &fb.x),
        ("y", &fa.y, &fb.y),
        ("z", &fa.z, &fb.z),
        ("ux", &fa.ux, &fb.ux),
        ("uy", &fa.uy, &fb.uy),
        ("uz", &fa.uz, &fb.uz),
        ("pressure", &fa.pressure, &fb.pressure),
        ("density", &fa.density, &fb.density),
        ("alpha[0]", &fa.alpha[0], &fb.alpha[0]),
    ] {
        same(name, x, y);
    }
    assert_eq!(fa.id, fb.id);
    assert!(fb.alpha[1].iter().all(|&x| x == 0.0));
    same("wall pressure", &a.walls.pressure, &b.walls.pressure);
    println!("one phase vs two with one absent: equal after {} steps (t = {:.4} s)", a.step, a.time);
}

/// The example scenes parse, run a few steps, and keep their fractions a
/// partition of unity.
#[test]
fn example_scenes_run() {
    for name in ["two_phase_mixing.toml", "three_phase_separation.toml"] {
        let mut sim = Simulation::new(common::scene_file(name));
        for _ in 0..3 {
            sim.step().unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        let (dev, low) = fraction_errors(&sim);
        assert!(dev <= 1e-6 && low >= 0.0, "{name}: {dev} {low}");
    }
}
