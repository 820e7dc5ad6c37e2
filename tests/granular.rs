//! Granular solids (issue 18; kernels/src/granular.rs): the Drucker-Prager
//! continuum in the step.

mod common;

use common::scene_text;
use porosph::pipeline::Simulation;

/// A column of sand (1600 kg/m^3) in a closed box, `w` wide, `h0` high.
fn column(d: f32, w: f32, h0: f32, depth: f32, extra: &str, dt: &str) -> String {
    format!(
        r#"
[simulation]
particle_spacing = {d}
end_time = 10.0
max_dt = {dt}

[[phase]]
name = "water"
density = 1000.0
viscosity = 0.001

[[wall]]
box = {{ min = [0.0, 0.0, 0.0], max = [{w}, {top}, {depth}] }}
container = true

[[solid]]
name = "sand"
box = {{ min = [0.0, 0.0, 0.0], max = [{w}, {h0}, {depth}] }}
density = 1600.0
shear_modulus = 1e6
lame_lambda = 1e6
model = "granular"
friction_angle = 30.0
{extra}
"#,
        top = h0 + 0.1
    )
}

/// Vertical stress against rho g depth of the particles deeper than
/// `below` under the column's top: (mean per-particle |error| / (rho g depth),
/// mean ratio), with the top at the highest particle + d/2.
fn vertical_stress_error(sim: &Simulation, d: f32, below: f32, rho: f32) -> (f64, f64, usize) {
    let s = &sim.solids;
    let g = -sim.params.gravity[1];
    let top = s.y.iter().copied().fold(f32::MIN, f32::max) + 0.5 * d;
    let (mut err, mut ratio, mut n) = (0.0f64, 0.0f64, 0usize);
    for i in 0..s.len() {
        let depth = top - s.y[i];
        if depth > below {
            let r = rho * g * depth;
            err += f64::from(((-s.syy[i] - r) / r).abs());
            ratio += f64::from(-s.syy[i] / r);
            n += 1;
        }
    }
    (err / n as f64, ratio / n as f64, n)
}

/// Where the error of [`vertical_stress_error`] sits: the mean ratio
/// sigma_yy / (rho g depth) of each layer (top first) and of the columns
/// next to a side wall, in a corner and inside, for a box `w` x `depth`.
fn stress_by_layer_and_column(sim: &Simulation, d: f32, below: f32, rho: f32, w: f32, depth: f32) -> String {
    let s = &sim.solids;
    let g = -sim.params.gravity[1];
    let top = s.y.iter().copied().fold(f32::MIN, f32::max) + 0.5 * d;
    let (nx, nz) = ((w / d).round() as i32, (depth / d).round() as i32);
    let layers = ((top / d).round()) as usize;
    let mut layer = vec![(0.0f64, 0usize); layers + 1];
    let mut class = [(0.0f64, 0usize); 3];
    for i in 0..s.len() {
        let dep = top - s.y[i];
        let r = f64::from(-s.syy[i] / (rho * g * dep));
        let k = ((dep / d - 0.5).round().max(0.0) as usize).min(layers);
        layer[k].0 += r;
        layer[k].1 += 1;
        if dep > below {
            let (ix, iz) = ((s.x[i] / d).floor() as i32, (s.z[i] / d).floor() as i32);
            let walls = usize::from(ix == 0 || ix == nx - 1) + usize::from(iz == 0 || iz == nz - 1);
            class[walls].0 += r;
            class[walls].1 += 1;
        }
    }
    let mean = |(a, n): (f64, usize)| if n > 0 { a / n as f64 } else { f64::NAN };
    let layers: Vec<String> = layer.iter().map(|&l| format!("{:.3}", mean(l))).collect();
    format!(
        "layers (top first) [{}]; columns: inside {:.4}, side wall {:.4}, corner {:.4}",
        layers.join(" "),
        mean(class[0]),
        mean(class[1]),
        mean(class[2])
    )
}

/// Issue 18, "a confined sand column at rest": 0.3 m of dry sand (1600
/// kg/m^3, phi = 30 deg, c = 0, G = lambda = 1 MPa) released from zero
/// stress in a box with frictionless walls (`wall_slip`, so the walls carry
/// none of its weight: no Janssen arching), max_dt 2 ms, 5 s. Returns (max
/// speed, mean per-particle |sigma_yy - rho g depth| / (rho g depth), mean
/// ratio) over the particles deeper than 3 d (the free surface's kernel
/// truncation sets the stress of the top layers).
fn sand_column_at_rest(d: f32, t_end: f64) -> (f32, f64, f64) {
    let mut sim = Simulation::new(scene_text(&column(d, 0.2, 0.3, 0.1, "wall_slip = true", "0.002")));
    common::run_until(&mut sim, t_end);
    let (err, ratio, n) = vertical_stress_error(&sim, d, 3.0 * d, 1600.0);
    let speed = sim.max_speed();
    println!("{}", stress_by_layer_and_column(&sim, d, 3.0 * d, 1600.0, 0.2, 0.1));
    println!(
        "d = {d} m, {} particles, t = {:.2} s: max speed {speed:.2e} m/s; sigma_yy / (rho g depth) over {n} \
         particles deeper than 3 d: mean {ratio:.4}, mean |error| {err:.4}",
        sim.solids.len(),
        sim.time
    );
    (speed, err, ratio)
}

/// The column settles and carries its weight (issue 18, "a confined sand
/// column at rest"): every speed below the issue's 1 mm/s after 5 s, and
/// vertical stress = rho g depth within the issue's 5 % per particle, at d
/// = 2 cm. Measured (2026-12-07, the walls' ghosts mirrored per wall with
/// the grain's volume, kernels/src/granular.rs "Edges and corners", and
/// their weight part bounded by the grain's own vertical stress): 2.2 %
/// (mean ratio 0.978; inside 0.981, side wall 0.976, corner 0.971; layer
/// means alternating by about 1 %, 0.967-0.993 below the 3rd), max speed
/// 2.9e-4 m/s; without the bound 3.6 % (mean 0.967; 0.974 / 0.964 / 0.936). The cubic spline's gradient bias puts the discrete
/// equilibrium at rho g depth / 1.02 (a column started lithostatic keeps
/// 0.978 in every column class).
///
/// Before the edges and corners were mirrored per wall: 6.1 % (mean
/// 0.962; inside 1.004, side wall 0.934, corner 0.863), 9.2e-5 m/s. Before
/// the walls' lithostatic mirror and mirrored velocity gradient: 10.6 %
/// (mean ratio 1.067; inside 1.131, side wall 1.021, corner 0.939). Tried
/// then: the grains' stress extrapolated onto each wall particle (Adami et
/// al. 2012) instead of the mirror: 72 %, 55 mm/s (it never settled); the
/// stress mirror with the weight term but v_b = M(v_i): 7.7 % (inside
/// 1.041, side 0.925, corner 0.770); the ghost stress continued with the
/// grains' own gradient along the wall (module doc of
/// kernels/src/granular.rs): 4.4 % at d = 2 cm, 8.7 % at d = 1 cm, and it
/// broke Example 7's tank. Before the walls' mirror velocity it never
/// settled (5-10 mm/s RMS).
#[test]
fn sand_column_comes_to_rest_carrying_its_weight() {
    let (speed, err, _) = sand_column_at_rest(0.02, 5.0);
    assert!(speed < 1e-3, "max speed {speed} m/s");
    assert!(err < 0.05, "vertical stress per-particle error {err}");
}

/// Sand at rest stays at rest (`initial_stress = "lithostatic"`): the
/// column of [`sand_column_at_rest`] started in the state it should settle
/// to, vertical stress rho g depth and half of it sideways (Jaky's K0 = 1 -
/// sin 30 deg), at d = 2 cm. Reference: that state, rho g depth, within
/// the issue's 5 % per particle after 1 s, and every speed below its 1
/// mm/s. It holds only if the discrete forces balance the lithostatic
/// stress at every grain, walls, edges and corners included (the cubic
/// spline's gradient bias of 2 % aside). Measured (2026-12-07): 1.53 % at
/// 1 s (mean 0.985 in every column class), 3.4e-4 m/s; without the ghosts'
/// weight bound 1.56 % at 1 s, 2.2 % and 6.5e-6 m/s at 5 s. With one mirror per grain and the walls' rest volumes as
/// the ghosts' (before 81543ad) the same start gave 6.3 % at 1 s (inside
/// 1.006, side wall 0.930, corner 0.868): the edge grains did not hold
/// their columns up (kernels/src/granular.rs, "Edges and corners").
#[test]
fn lithostatic_sand_column_stays_at_rest() {
    let d = 0.02;
    let text = column(d, 0.2, 0.3, 0.1, "wall_slip = true\ninitial_stress = \"lithostatic\"", "0.002");
    let mut sim = Simulation::new(scene_text(&text));
    let (err0, ratio0, _) = vertical_stress_error(&sim, d, 3.0 * d, 1600.0);
    assert!(err0 < 1e-5 && (ratio0 - 1.0).abs() < 1e-5, "the start: error {err0}, ratio {ratio0}");
    let s = &sim.solids;
    for i in 0..s.len() {
        let (kx, kz) = (s.sxx[i] / s.syy[i], s.szz[i] / s.syy[i]);
        assert!((kx - 0.5).abs() < 1e-5 && (kz - 0.5).abs() < 1e-5, "grain {i}: K0 {kx}, {kz}");
        assert!(s.sxy[i] == 0.0 && s.sxz[i] == 0.0 && s.syz[i] == 0.0, "grain {i}: shear at rest");
    }
    common::run_until(&mut sim, 1.0);
    let (err, ratio, n) = vertical_stress_error(&sim, d, 3.0 * d, 1600.0);
    let speed = sim.max_speed();
    println!("{}", stress_by_layer_and_column(&sim, d, 3.0 * d, 1600.0, 0.2, 0.1));
    println!(
        "t = {:.2} s: max speed {speed:.2e} m/s; over {n} grains: mean ratio {ratio:.4}, error {err:.4}",
        sim.time
    );
    assert!(err < 0.05, "vertical stress per-particle error {err}");
    assert!(speed < 1e-3, "max speed {speed} m/s");
}

/// Both criteria at d = 1 cm (6,000 grains), after 10 s (ignored for its
/// 6-9 minutes; run with `--ignored`). The column rings in its first elastic
/// mode (a quarter wave over its height, period 4 H / c = 28 ms with c =
/// 43 m/s), damped only by the artificial viscosity, whose rate alpha c h
/// k^2 / 10 halves with h: at d = 1 cm its speed amplitude is still about
/// 2.5 mm/s at 5 s, and the stress sampled at whole seconds swings with it.
/// Measured (2026-12-07, the ghosts' weight bounded by the grain's own
/// stress), mean ratio / per-particle error / max speed at 1-10 s: 0.732 /
/// 26.8 % / 23.5 mm/s (1 s), 1.161 / 16.1 % / 12.8 mm/s, 1.165 / 16.5 % /
/// 1.0 mm/s, 1.023 / 2.3 % / 5.1 mm/s, 0.939 / 6.1 % / 2.6 mm/s (5 s), 0.940
/// / 6.1 % / 0.26 mm/s, 0.969 / 3.1 % / 1.06 mm/s (7 s), 0.987 / 1.3 % /
/// 0.53 mm/s, 0.986 / 1.4 % / 0.06 mm/s, and at 10 s 0.980 / 2.0 % / 0.22
/// mm/s (inside 0.981, side wall 0.979, corner 0.973): the criterion holds
/// from 8 s on. Before that bound (508075c) the same swing, at 10 s 3.2 %
/// (0.969), 0.21 mm/s. Before the edges and corners were mirrored per wall:
/// 10.1 % at 5 s (mean 1.052, with the compression cone), 3.2 mm/s.
#[test]
#[ignore]
fn sand_column_at_1_cm_comes_to_rest_carrying_its_weight() {
    let (speed, err, _) = sand_column_at_rest(0.01, 10.0);
    assert!(speed < 1e-3, "d = 1 cm: max speed {speed} m/s at 10 s");
    assert!(err < 0.05, "d = 1 cm: vertical stress per-particle error {err} at 10 s");
}

/// A granular run resumed from a checkpoint, on another thread count, is
/// the same run: the stress and plastic strain are the state that the
/// checkpoint carries (`SolidStore::sxx` .. `plastic_strain`). A column of
/// sand on a rough floor, released as a cube so that it yields and flows.
#[test]
fn resumed_granular_run_is_bitwise_the_uninterrupted_run() {
    use porosph::io::checkpoint::{load_checkpoint, write_checkpoint, RunInfo};
    let text = column(0.02, 0.4, 0.2, 0.1, "", "0.002").replace("max = [0.4, 0.2, 0.1] }", "max = [0.12, 0.2, 0.1] }");
    let info = RunInfo {
        frames_written: 0,
        next_frame_time: 0.0,
        frame_every: 0.01,
        stop_time: None,
        stop_step: None,
        checkpoint_every: "10steps".to_string(),
        keep: 1,
        compress: false,
    };
    let dir = common::TempDir::new("granular-restart");
    let ckpt = dir.path("ckpt.h5");
    let (n, m) = (40, 40);
    let steps = |sim: &mut Simulation, k: u64| {
        for _ in 0..k {
            sim.step().unwrap_or_else(|e| panic!("{e}"));
        }
    };
    common::with_threads(2, || {
        let mut straight = Simulation::new(scene_text(&text));
        steps(&mut straight, n + m);
        let mut first = Simulation::new(scene_text(&text));
        steps(&mut first, n);
        write_checkpoint(&ckpt, &first, &info, None).unwrap_or_else(|e| panic!("{e}"));
        let resumed = common::with_threads(1, || {
            let (mut resumed, _) = load_checkpoint(&ckpt).unwrap_or_else(|e| panic!("{e}"));
            steps(&mut resumed, m);
            resumed
        });
        let plastic = straight.solids.plastic_strain.iter().copied().fold(0.0, f32::max);
        println!("{} grains, t = {:.3} s, largest plastic strain {plastic:.3}", straight.solids.len(), straight.time);
        assert!(plastic > 1e-2, "the test needs a flowing column");
        assert_eq!(resumed.dt.to_bits(), straight.dt.to_bits());
        common::assert_same_bits(&common::solid_bits(&resumed.solids), &common::solid_bits(&straight.solids));
    });
}

/// Issue 18, "dry granular column collapse": a column L0 long and H0 = a L0
/// high against the end wall of a quasi-2D channel 0.06 m wide (smooth side
/// walls, `wall_slip = ["z"]`, and a rough floor and end wall), d = 1 cm,
/// phi = 30 deg with the default plane-strain cone, released at rest; at
/// 1.5 s (at rest: below 1 cm/s) the runout (L_inf - L0) / L0, L_inf the front (the 99th
/// percentile of x). Reference: the experiments' fits (Lube et al. 2005,
/// Lajeunesse et al. 2005), about 1.2 a for a < 1.8 and 1.9 a^(2/3) above;
/// their constants depend on the material (Balmforth & Kerswell 2005 find
/// them material-dependent and different between wide and narrow
/// channels), so the band is the fit +-20 %. At a = 0.5 the top stays
/// where it was (within d / 2).
///
/// Measured (2026-12-07, the walls' ghosts mirrored per wall, their weight
/// bounded): a = 0.5: 0.561 (fit 0.60, -6.5 %), top 0.100 m; a = 2: 3.175
/// (fit 3.02, +5.1 %), 0.3 mm/s at 1.5 s. Without the bound: 0.590 and
/// 3.351 (1.1 mm/s). With one mirror per grain (2026-12-05): 0.565 and
/// 3.249. Before the walls' lithostatic mirror (2026-12-04): 0.529 and
/// 3.015. With rough side walls (6 particles apart,
/// they hold the flow) and the compression cone (1.8 times stronger in
/// plane strain) the runouts were 0.21 and 1.25; either change alone gave
/// 0.41-0.42 (a = 0.5) and 2.06-2.44 (a = 2).
#[test]
fn column_collapse_runout_is_in_the_experiments_band() {
    let d = 0.01f32;
    for (a, l0) in [(0.5f32, 0.2f32), (2.0, 0.1)] {
        let h0 = a * l0;
        let text = format!(
            "[simulation]\nparticle_spacing = {d}\nend_time = 2.0\nmax_dt = 0.002\n\n[[phase]]\nname = \"water\"\n\
             density = 1000.0\nviscosity = 0.001\n\n[[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [1.2, 0.4, 0.06] }}\n\
             container = true\n\n[[solid]]\nname = \"sand\"\nbox = {{ min = [0.0, 0.0, 0.0], max = [{l0}, {h0}, 0.06] }}\n\
             density = 1600.0\nshear_modulus = 1e6\nlame_lambda = 1e6\nmodel = \"granular\"\nfriction_angle = 30.0\n\
             wall_slip = [\"z\"]\n"
        );
        let mut sim = Simulation::new(scene_text(&text));
        common::run_until(&mut sim, 1.5);
        let mut x: Vec<f32> = sim.solids.x.clone();
        x.sort_by(f32::total_cmp);
        let front = x[(0.99 * (x.len() - 1) as f32) as usize] + 0.5 * d;
        let top = sim.solids.y.iter().copied().fold(f32::MIN, f32::max) + 0.5 * d;
        let fit = if a < 1.8 { 1.2 * a } else { 1.9 * a.powf(2.0 / 3.0) };
        let runout = (front - l0) / l0;
        println!(
            "a = {a}: runout (L - L0)/L0 = {runout:.3} (fit {fit:.2}), top {top:.3} m (H0 {h0}), max speed {:.4} m/s",
            sim.max_speed()
        );
        assert!((runout - fit).abs() <= 0.2 * fit, "a = {a}: runout {runout} outside the fit {fit} +-20 %");
        assert!(sim.max_speed() < 0.01, "a = {a}: not at rest at 1.5 s ({} m/s)", sim.max_speed());
        if a < 1.0 {
            assert!((top - h0).abs() <= 0.5 * d, "a = {a}: the top moved to {top} m (H0 {h0})");
        }
    }
}

/// Issue 18, "a cohesive column taller than its critical height collapses
/// and one below half of it stands": a vertical cut of cohesive sand
/// (phi = 30 deg, c = 906 Pa, 1600 kg/m^3), 0.3 m long, in the quasi-2D
/// channel of the collapse test, released at rest; its end wall is smooth
/// too (`wall_slip = ["x", "z"]`), a plane of symmetry, so that the bank
/// does not hang on it. Reference: the
/// critical height of an unsupported vertical cut, H_c = 2 c cos(phi) /
/// ((1 - sin(phi)) rho g) = 0.20 m here (Rankine; Mohr-Coulomb, which the
/// plane-strain cone matches in this flow). A bank of 2 H_c must fail (a
/// wedge slides out: its front moves by more than 5 d; the bank behind it
/// keeps its height) and one of 0.45 H_c must stand (front and top within
/// d / 2 after 1 s).
///
/// Measured (2026-12-07): 0.45 H_c: front 0.300 m, top 0.090 m (unmoved),
/// 3e-4 m/s; 2 H_c: front 0.507 m (+0.207 m; the wedge's width at the
/// top is 0.23 m), top 0.389 m (without the ghosts' weight bound 0.481 m,
/// 0.390 m; 2026-12-05: 0.533 m, 0.389 m; 2026-12-04: 0.535 m, 0.388 m). With a rough end wall a 0.1 m long bank of
/// 2 H_c hung on it and stood (front +2 mm).
#[test]
fn cohesive_cut_stands_below_its_critical_height_and_falls_above() {
    let (d, phi, rho, g) = (0.01f32, 30f32.to_radians(), 1600.0f32, 9.81f32);
    let c = 906.0f32;
    let hc = 2.0 * c * phi.cos() / ((1.0 - phi.sin()) * rho * g);
    // Longer than the failure wedge, H tan(45 deg - phi / 2) = 0.23 m at 2 H_c.
    let l0 = 0.3f32;
    for (ratio, stands) in [(0.45f32, true), (2.0, false)] {
        let h0 = (ratio * hc / d).round() * d;
        let text = format!(
            "[simulation]\nparticle_spacing = {d}\nend_time = 2.0\nmax_dt = 0.002\n\n[[phase]]\nname = \"water\"\n\
             density = 1000.0\nviscosity = 0.001\n\n[[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [1.0, 0.6, 0.06] }}\n\
             container = true\n\n[[solid]]\nname = \"sand\"\nbox = {{ min = [0.0, 0.0, 0.0], max = [{l0}, {h0}, 0.06] }}\n\
             density = {rho}\nshear_modulus = 1e6\nlame_lambda = 1e6\nmodel = \"granular\"\nfriction_angle = 30.0\n\
             cohesion = {c}\nwall_slip = [\"x\", \"z\"]\n"
        );
        let mut sim = Simulation::new(scene_text(&text));
        common::run_until(&mut sim, 1.0);
        let front = sim.solids.x.iter().copied().fold(f32::MIN, f32::max) + 0.5 * d;
        let top = sim.solids.y.iter().copied().fold(f32::MIN, f32::max) + 0.5 * d;
        println!(
            "H0 = {h0:.2} m = {:.2} H_c (H_c = {hc:.3} m): front {front:.3} m (L0 {l0}), top {top:.3} m, max speed {:.4} m/s",
            h0 / hc,
            sim.max_speed()
        );
        if stands {
            assert!(front - l0 <= 0.5 * d && h0 - top <= 0.5 * d, "H0 = {h0}: should stand");
        } else {
            assert!(front - l0 > 5.0 * d, "H0 = {h0}: should fall");
        }
    }
}

/// Issue 18, "Example 7 runs its end time without a step error, each
/// phase's mass (outer + inner) conserved to 1e-6": `scenes/example7_wet_sand.toml`
/// (two sand columns, a = 2, collapsing into a shallow pool, wet cohesion
/// 2000 and 200 Pa, d = 1 cm, max_dt 2 ms) to its end time, 2 s. Reference:
/// mass conservation (no particle is created or deleted, P §6). Also: every
/// grain stays inside its tank (within d / 2 of the walls' inner faces:
/// before `Granular::wall_contact` grains were pushed 6-14 mm through the
/// floor and a side wall), the water has soaked into the sand, and, as in
/// the paper's Fig. 11, the larger wet cohesion runs out less.
///
/// Measured (2026-12-07): fronts 0.170 m (2000 Pa) and 0.201 m (200 Pa),
/// tops 0.169 and 0.116 m, mean saturation 0.217 and 0.252. Before the
/// ghosts' weight was bounded by the grain's own stress (508075c): tops
/// 0.303 and 0.115 m: one grain of the 2000 Pa column (id 22796), one of a
/// pair with two fluid particles thrown from the collapse's front, rose
/// along the smooth back wall accelerating at about (5.6, 14) m/s^2
/// besides gravity from 0.55 to 0.9 s (reaching 1.8 m/s) and stayed under
/// the ceiling at (0.470, 0.298, 0.050) m from 1.0 s on, held by the
/// ceiling's ghosts' weight term (kernels/src/granular.rs). With the
/// ghosts summed pair by pair (81543ad) no grain flew: fronts 0.167 and
/// 0.205 m, tops 0.170 and 0.115 m (2026-12-05:
/// 0.169 and 0.200 m, tops 0.169 and 0.121 m, 0.223 and 0.247). Before the
/// walls' lithostatic mirror (2026-12-04): water 2.88 kg, relative change below 1e-15;
/// mean saturation sum_k phi_sk 0.216 and 0.239; front (99th percentile of
/// x, + d / 2) 0.173 m (runout 0.73 L0) with 2000 Pa against 0.205 m
/// (1.05 L0) with 200 Pa, tops 0.161 and 0.116 m; a dry column of a = 2
/// runs out 3.0 L0 in air (the collapse test above). 56 s.
#[test]
fn example7_runs_to_its_end_conserving_water_and_wet_cohesion_shortens_the_runout() {
    let d = 0.01f32;
    let mut sim = Simulation::new(common::scene_file("example7_wet_sand.toml"));
    let m0 = sim.phase_masses();
    let end = sim.scene.simulation.end_time;
    common::run_until(&mut sim, end);
    for (k, (m, m0)) in sim.phase_masses().iter().zip(&m0).enumerate() {
        assert!(((m - m0) / m0).abs() < 1e-6, "phase {k}: mass {m0} -> {m} kg");
    }
    let s = &sim.solids;
    let (mut front, mut top, mut sat) = ([0f32; 2], [0f32; 2], [0f32; 2]);
    for b in 0..2u32 {
        let of = |i: &usize| s.body[*i] == b;
        let mut x: Vec<f32> = (0..s.len()).filter(of).map(|i| s.x[i]).collect();
        let n = x.len();
        x.sort_by(f32::total_cmp);
        front[b as usize] = x[(0.99 * (n - 1) as f32) as usize] + 0.5 * d;
        top[b as usize] = (0..s.len()).filter(of).map(|i| s.y[i]).fold(f32::MIN, f32::max) + 0.5 * d;
        sat[b as usize] = (0..s.len()).filter(of).map(|i| s.saturation[i]).sum::<f32>() / n as f32;
        let z0 = if b == 0 { 0.0 } else { 0.1 };
        for i in (0..s.len()).filter(of) {
            let inside = s.x[i] > -0.5 * d
                && s.x[i] < 0.5 + 0.5 * d
                && s.y[i] > -0.5 * d
                && s.z[i] > z0 - 0.5 * d
                && s.z[i] < z0 + 0.06 + 0.5 * d;
            assert!(inside, "grain {i} of body {b} left its tank: ({}, {}, {})", s.x[i], s.y[i], s.z[i]);
        }
    }
    println!(
        "t = {:.2} s: wet cohesion 2000 Pa: front {:.3} m, top {:.3} m, mean saturation {:.3}; 200 Pa: front {:.3} m, \
         top {:.3} m, mean saturation {:.3}",
        sim.time, front[0], top[0], sat[0], front[1], top[1], sat[1]
    );
    assert!(sat[0] > 0.05 && sat[1] > 0.05, "the sand did not soak: {sat:?}");
    assert!(front[0] + 2.0 * d < front[1], "the larger wet cohesion should run out less: fronts {front:?}");
}

/// Issue 18, "wet vs dry: with the wet cohesion law, runout decreases with
/// cohesion at intermediate saturation, and a fully saturated column
/// behaves like the dry one within 5 %": the a = 2 column of the collapse
/// test (L0 0.1 m, H0 0.2 m, d = 1 cm, smooth sides), damp sand with its
/// moisture held fixed (`saturation`, no flow), at the law's wettest
/// S = 0.74 with wet_cohesion 100 and 300 Pa (Rankine's critical heights
/// 0.022 and 0.066 m, both below H0, so both fall), and at S = 1 with
/// 300 Pa; 1.5 s each. Reference: the dry runout of the same column (3.0
/// L0, the collapse test), and Lu & Likos' law, which adds nothing at S = 1
/// (exactly: g(1) = 0, so the saturated run is the dry run bit for bit;
/// this part checks the law's end point in the step, not more).
///
/// Measured (2026-12-07): dry 3.175 L0; S = 0.74: 1.713 (100 Pa), 0.856
/// (300 Pa); S = 1, 300 Pa: 3.175 (without the ghosts' weight bound 3.351,
/// 1.735, 0.850, 3.351; 2026-12-05: 3.249, 1.751, 0.870, 3.249;
/// 2026-12-04, before the walls' lithostatic mirror: 3.015, 1.732, 0.909,
/// 3.015). At 1.5 s all at rest (< 1e-3 m/s).
#[test]
fn damp_sand_runs_out_less_and_saturated_sand_like_dry() {
    let d = 0.01f32;
    let (l0, h0) = (0.1f32, 0.2f32);
    let runout = |extra: &str| {
        let text = format!(
            "[simulation]\nparticle_spacing = {d}\nend_time = 2.0\nmax_dt = 0.002\n\n[[phase]]\nname = \"water\"\n\
             density = 1000.0\nviscosity = 0.001\n\n[[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [1.2, 0.4, 0.06] }}\n\
             container = true\n\n[[solid]]\nname = \"sand\"\nbox = {{ min = [0.0, 0.0, 0.0], max = [{l0}, {h0}, 0.06] }}\n\
             density = 1600.0\nshear_modulus = 1e6\nlame_lambda = 1e6\nmodel = \"granular\"\nfriction_angle = 30.0\n\
             wall_slip = [\"z\"]\n{extra}\n"
        );
        let mut sim = Simulation::new(scene_text(&text));
        common::run_until(&mut sim, 1.5);
        let mut x: Vec<f32> = sim.solids.x.clone();
        x.sort_by(f32::total_cmp);
        let r = (x[(0.99 * (x.len() - 1) as f32) as usize] + 0.5 * d - l0) / l0;
        println!("{extra:?}: runout (L - L0)/L0 = {r:.3}, max speed {:.4} m/s", sim.max_speed());
        r
    };
    let dry = runout("");
    let c100 = runout("saturation = 0.74\nwet_cohesion = 100.0");
    let c300 = runout("saturation = 0.74\nwet_cohesion = 300.0");
    let wet = runout("saturation = 1.0\nwet_cohesion = 300.0");
    let step = d / l0;
    assert!(
        c100 < dry - step && c300 < c100 - step,
        "runout should fall with the wet cohesion: dry {dry}, 100 Pa {c100}, 300 Pa {c300}"
    );
    assert!((wet - dry).abs() <= 0.05 * dry, "saturated {wet} vs dry {dry}");
}
