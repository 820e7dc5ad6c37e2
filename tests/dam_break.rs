//! Dam break against Martin & Moyce (1952), core issue.
//!
//! A water column a wide and 2a high (n^2 = 2) collapses along a dry floor.
//! Reference: the surge-front positions Z = x/a at T = t sqrt(2g/a) measured
//! by J. C. Martin and W. J. Moyce, "An experimental study of the collapse of
//! liquid columns on a rigid horizontal plane", Phil. Trans. R. Soc. A 244
//! (1952) 312-324, for n^2 = 2 (a = 2.25 in), as tabulated in SPH/MPS
//! validation papers (e.g. Koshizuka & Oka 1996, Nucl. Sci. Eng. 123).
//! Tolerance: 10 % (the issue's bound), checked two ways, because the
//! experiment starts late: its gate takes a finite time to lift, so every
//! numerical front (SPH, VOF, MPS) leads the measured one early on.
//! 1. The front speed dZ/dT between T = 1.43 and T = 2.98 (no time origin
//!    needed) within 10 % of the measured speed.
//! 2. Z(T) at every data point with T <= 3 within 10 %, after the standard
//!    gate-release correction Delta T = 0.175 (the value used by Lethe,
//!    chaos-polymtl/lethe, examples/multiphysics/dam-break). It is taken as
//!    published, not fitted here. The uncorrected errors are printed too.

mod common;

use porosph::pipeline::Simulation;

/// (T, Z) of Martin & Moyce 1952, n^2 = 2.
const MARTIN_MOYCE: [(f64, f64); 15] = [
    (0.41, 1.11),
    (0.84, 1.22),
    (1.19, 1.44),
    (1.43, 1.67),
    (1.63, 1.89),
    (1.83, 2.11),
    (1.98, 2.33),
    (2.20, 2.56),
    (2.32, 2.78),
    (2.51, 3.00),
    (2.65, 3.22),
    (2.83, 3.44),
    (2.98, 3.67),
    (3.11, 3.89),
    (3.33, 4.11),
];

#[test]
fn surge_front_follows_martin_moyce() {
    let a = 0.1f64;
    let d = 0.005;
    let scene = common::scene_text(&format!(
        r#"[simulation]
particle_spacing = {d}
end_time = 1.0
max_dt = 0.001
frame_interval = 1.0
[[phase]]
name = "water"
density = 1000.0
viscosity = 0.001
[[fluid]]
box = {{ min = [0.0, 0.0, 0.0], max = [{a}, {h}, 0.05] }}
fractions = {{ water = 1.0 }}
[[wall]]
box = {{ min = [0.0, 0.0, 0.0], max = [0.6, 0.3, 0.05] }}
container = true
open_top = true
"#,
        h = 2.0 * a
    ));
    let g = 9.81f64;
    let t_scale = (a / (2.0 * g)).sqrt(); // t = T t_scale
    let mut sim = Simulation::new(scene);
    let mut series = vec![(0.0f64, front(&sim) / a)];
    while sim.time < 3.2 * t_scale {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        series.push((sim.time / t_scale, front(&sim) / a));
    }
    const GATE_DT: f64 = 0.175;
    let (mut worst, mut worst_raw) = (0.0f64, 0.0f64);
    println!("   T    Z (M&M)  Z (porosph)  error   Z (porosph, T - 0.175)  error");
    for &(t_ref, z_ref) in MARTIN_MOYCE.iter().filter(|&&(t, _)| t <= 3.0) {
        let z_raw = interpolate(&series, t_ref);
        let z = interpolate(&series, t_ref - GATE_DT);
        let (e_raw, e) = ((z_raw - z_ref) / z_ref, (z - z_ref) / z_ref);
        worst_raw = worst_raw.max(e_raw.abs());
        worst = worst.max(e.abs());
        println!("{t_ref:5.2}  {z_ref:6.2}  {z_raw:10.3}  {:+6.1} %  {z:10.3}  {:+6.1} %", 100.0 * e_raw, 100.0 * e);
    }
    let (t0, z0) = MARTIN_MOYCE[3];
    let (t1, z1) = MARTIN_MOYCE[12];
    let speed_ref = (z1 - z0) / (t1 - t0);
    let speed = (interpolate(&series, t1) - interpolate(&series, t0)) / (t1 - t0);
    let speed_err = (speed - speed_ref) / speed_ref;
    println!(
        "dam break: {} fluid particles, d = {d} m, a = {a} m: front speed dZ/dT {speed:.3} vs {speed_ref:.3} \
         ({:+.1} %); worst error in Z {:.1} % with the gate correction, {:.1} % without",
        sim.fluid.len(),
        100.0 * speed_err,
        100.0 * worst,
        100.0 * worst_raw
    );
    assert!(speed_err.abs() <= 0.10, "front speed off by {:.1} %", 100.0 * speed_err);
    assert!(worst <= 0.10, "surge front off Martin & Moyce by {:.1} %", 100.0 * worst);
}

/// Leading edge of the surge: the largest x of a fluid particle plus half a
/// particle spacing (the particle's extent), from the wall at x = 0.
fn front(sim: &Simulation) -> f64 {
    let h = sim.params.h as f64;
    sim.fluid.x.iter().fold(0.0f64, |m, &x| m.max(x as f64)) + 0.5 * h
}

fn interpolate(s: &[(f64, f64)], t: f64) -> f64 {
    let k = s.partition_point(|&(ti, _)| ti < t).clamp(1, s.len() - 1);
    let ((t0, z0), (t1, z1)) = (s[k - 1], s[k]);
    z0 + (z1 - z0) * (t - t0) / (t1 - t0)
}
