//! Hydrostatic tank at rest (core issue): after 1 s, the IISPH pressure
//! equals rho g depth and the fluid is incompressible to 0.1 %.
//!
//! Reference: hydrostatics, p = rho |g| (y_s - y) with the free surface y_s
//! at the top of the initial fluid block (the fill height; the column is
//! incompressible to 0.1 %, so y_s moves by well under a particle spacing).

mod common;

use porosph::pipeline::Simulation;
use porosph::scene::{PressureWarmStart, WallRowsChoice};

#[test]
fn pressure_is_rho_g_depth_after_one_second() {
    hydrostatic_column(0.0);
}

/// The same column with the Chebyshev semi-iteration over the Jacobi
/// sweeps (`chebyshev_radius = 0.9`, kernels/src/chebyshev.rs): the same
/// criteria against hydrostatics, and fewer sweeps than plain Jacobi over
/// the same second (both counted here; deterministic, not a timing). The
/// bound, at most 0.7 of Jacobi's, fails when the extrapolation is dropped.
///
/// Measured 2026-12-05 (sweeps in 1 s; the deep particles' mean pressure
/// against rho g depth, time mean over 0.8-1 s and its range over single
/// steps; mean absolute error per particle over mean rho g depth):
///
/// | radius | sweeps | time mean | single steps | per particle |
/// |---|---|---|---|---|
/// | 0 (plain Jacobi) | 10,814 | +0.55 % | -5.4 / +5.5 % | 15.3 % |
/// | 0.8 | 6,887 | +0.71 % | -4.9 / +7.2 % | 15.8 % |
/// | 0.9 | 5,262 | +0.59 % | -7.2 / +8.7 % | 16.2 % |
/// | 0.9, rows at p = 0 not extrapolated (committed) | 5,261 | +0.68 % | -5.7 / +8.6 % | 15.9 % |
/// | 0.95 | 4,145 | +0.48 % | -15 / +19 % | 16.7 % |
/// | 0.98 | 3,448 | +0.68 % | -56 / +47 % | 26.3 % |
///
/// Why the spread grows with the radius: the smooth pressure modes that
/// barely change the density (a uniform offset of a closed pool is one:
/// sum_j V_j grad W_ij is about 0 in the bulk) are what the 0.1 % density
/// criterion does not fix; plain Jacobi hardly moves them from the warm
/// start (0.5 of the last pressure), which anchors them from step to
/// step, and the semi-iteration moves them by more. A fuller warm start
/// does not help: 0.75 or 1.0 of the last pressure gives 30 % / 55 % per
/// particle (Jacobi and Chebyshev alike; the halving is what lets their
/// noise decay). Counting expansion in the stop criterion (|residual| of
/// rows with p > 0) changes nothing here (4,148 sweeps, -14 / +19 %).
#[test]
fn chebyshev_column_is_rho_g_depth_in_fewer_sweeps() {
    let jacobi = hydrostatic_column(0.0);
    let chebyshev = hydrostatic_column(0.9);
    println!("sweeps in 1 s: Jacobi {jacobi}, Chebyshev (rho 0.9) {chebyshev}");
    assert!((chebyshev as f64) <= 0.7 * jacobi as f64, "Chebyshev {chebyshev} sweeps against Jacobi's {jacobi}");
}

/// The same column with `pressure_warm_start = "hydrostatic"` (each solve
/// starts from half the last pressure and half rho |g| depth,
/// kernels/src/hydrostatic.rs): the same criteria against hydrostatics in
/// at most a third of the sweeps of the plain half warm start (both
/// counted here; deterministic, not a timing).
///
/// Measured 2026-12-05 (the commit that brought it): 1,223 sweeps in 1 s
/// (2.4 a step; the minimum is 2) against the half warm start's 10,814;
/// deep particles' time-mean pressure +0.59 % off rho g depth (+0.55 %),
/// single steps -3.1 / +4.4 % (-5.4 / +5.5 %), per particle 10.1 %
/// (15.3 %); largest speed at 1 s 0.137 m/s.
#[test]
fn hydrostatic_warm_start_column_is_rho_g_depth_in_a_third_of_the_sweeps() {
    let half = hydrostatic_column(0.0);
    let hydrostatic = hydrostatic_column_from(0.0, PressureWarmStart::Hydrostatic);
    println!("sweeps in 1 s: half warm start {half}, hydrostatic warm start {hydrostatic}");
    assert!(3 * hydrostatic <= half, "hydrostatic warm start {hydrostatic} sweeps against the half's {half}");
}

/// Runs scenes/hydrostatic.toml for 1 s with `chebyshev_radius` and
/// checks the pressure against rho g depth; returns the pressure solve's
/// sweeps over the run.
fn hydrostatic_column(chebyshev_radius: f32) -> u64 {
    hydrostatic_column_from(chebyshev_radius, PressureWarmStart::Half)
}

/// [`hydrostatic_column`] with the solve's warm start `warm`.
fn hydrostatic_column_from(chebyshev_radius: f32, warm: PressureWarmStart) -> u64 {
    let mut scene = common::scene_file("hydrostatic.toml");
    scene.simulation.chebyshev_radius = chebyshev_radius;
    scene.simulation.pressure_warm_start = warm;
    let fill = 0.3f32; // fluid block top in scenes/hydrostatic.toml
    let rho0 = scene.phases[0].density;
    let g = -scene.simulation.gravity[1];
    let d = scene.simulation.particle_spacing;
    let target = scene.simulation.max_density_error;
    let max_it = scene.simulation.max_iterations;
    let mut sim = Simulation::new(scene);
    // The tank is not at rest (the lattice start relaxes; issue 15 and
    // `tank_at_rest_per_particle`), so the deep pressure fluctuates from
    // step to step: its mean moved by about +-5 % between steps around
    // t = 1 s. A single snapshot is then a draw from that spread, and which
    // draw depends on rounding: the same code built for AVX-512 and for
    // AVX2 (lane sums in another order) agreed to 1e-6 after one step but
    // ended at 0.8 % and 4.8 % at t = 1 s. The hydrostatic pressure is the
    // time mean, so the test averages the deep particles' pressure and
    // reference over every step of the last 0.2 s.
    let mut worst = 0.0f32;
    // Sums over the particles below the top two layers of the fill: count,
    // pressure, rho g depth and the absolute difference.
    let deep_sums = |sim: &Simulation| {
        let f = &sim.fluid;
        let (mut n, mut sp, mut sref, mut sabs) = (0usize, 0.0f64, 0.0f64, 0.0f64);
        for i in (0..f.len()).filter(|&i| f.y[i] < fill - 2.0 * d) {
            let p_ref = (rho0 * g * (fill - f.y[i])) as f64;
            n += 1;
            sp += f.pressure[i] as f64;
            sref += p_ref;
            sabs += (f.pressure[i] as f64 - p_ref).abs();
        }
        (n, sp, sref, sabs)
    };
    let (mut steps, mut sp, mut sref, mut sabs) = (0usize, 0.0f64, 0.0f64, 0.0f64);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut n_deep, mut n_sum) = (usize::MAX, 0usize);
    let mut sweeps = 0u64;
    // The solver must reach its target in every step, never stopping at
    // the iteration cap.
    while sim.time < 1.0 - 1e-9 {
        let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
        assert!(st.iterations < max_it, "pressure solve hit the iteration cap at t = {}", sim.time);
        sweeps += u64::from(st.iterations);
        worst = worst.max(st.density_error);
        if sim.time > 0.8 + 1e-9 {
            let (n, p, r, a) = deep_sums(&sim);
            assert!(n > sim.fluid.len() / 2);
            n_deep = n_deep.min(n);
            n_sum += n;
            steps += 1;
            sp += p;
            sref += r;
            sabs += a;
            lo = lo.min(p / r - 1.0);
            hi = hi.max(p / r - 1.0);
        }
    }
    assert!(worst <= target);
    assert!(steps >= 50, "only {steps} steps in the averaging window");

    let f = &sim.fluid;
    // Mean density error as IISPH measures it (SPlisHSPlasH's
    // avg_density_err): the mean compression max(rho/rho0 - 1, 0) over all
    // fluid particles, here from the densities after the last step.
    let density_err = (0..f.len()).map(|i| (f.density[i] / rho0 - 1.0).max(0.0) as f64).sum::<f64>() / f.len() as f64;
    let mean_err = (sp - sref).abs() / sref;
    let mean_abs_err = sabs / sref;
    println!(
        "hydrostatic (chebyshev_radius {chebyshev_radius}): {steps} steps in 0.8 s < t <= 1 s, at least {n_deep} particles below the top two layers; \
         time-mean pressure {:.1} Pa vs rho g depth {:.1} Pa: relative error of the mean {:.4} (single steps {:+.4} to {:+.4}), \
         mean absolute error / mean reference {:.4}; mean compression max(rho/rho0 - 1, 0) = {:.5}; \
         solver: {} iterations, predicted error {:.5} (worst over all steps {:.5}); max speed {:.2e} m/s",
        sp / n_sum as f64,
        sref / n_sum as f64,
        mean_err,
        lo,
        hi,
        mean_abs_err,
        density_err,
        sim.last.iterations,
        sim.last.density_error,
        worst,
        sim.last.max_speed
    );
    assert!(mean_err < 0.02, "mean pressure off by {:.2} %", 100.0 * mean_err);
    // The solver stops on its linearised prediction of the compression; the
    // compression measured after the step may exceed it by the
    // linearisation error, which we bound at half the target.
    assert!(density_err <= 1.5 * target as f64, "mean density error {:.4} %", 100.0 * density_err);
    sweeps
}

/// `wall_rows = "lattice"` (issue 15, bench/RESULTS.md "The container's
/// edges and corners"): in scenes/hydrostatic.toml's column the fluid
/// along the container's vertical and floor edges (within d of two walls)
/// and in its floor corners (three) carries rho g depth, as the fluid
/// elsewhere does, within 10 % (sum of p over sum of rho g depth over the
/// group's particles deeper than 3 d, every step of 0.1-0.2 s). Reference:
/// hydrostatics. With the default Akinci wall rows those groups read 1.26
/// and 2.93 over the same window (2.1 and 3.5 at step 10; printed here):
/// the wall rows where walls meet keep p = 0.
///
/// Measured 2026-12-06: lattice rows, edges 0.939 and corners 1.042 over
/// 0.1-0.2 s (no wall within d 0.988, one 1.000); Akinci rows 1.264 and
/// 2.926 (0.996, 0.960).
///
/// The corner group is four particles, and its figure depends on the
/// window (measured 2026-12-08, lattice rows, the same run): corners
/// 1.042 / 0.897 / 0.543 over steps 51-100 / 101-150 / 151-200, edges
/// 0.939 / 0.983 / 1.012. Their pressure swings by a factor of two from
/// step to step also with the solve at 1e-5 (bench/RESULTS.md, "The deep
/// pool's late growth"), so this test holds the corners' mean over its
/// window only; a per-row check of the corners at rest is still to be
/// written.
#[test]
fn lattice_wall_rows_hold_the_container_edges_and_corners_at_rho_g_depth() {
    let run = |rows: WallRowsChoice| {
        let mut scene = common::scene_file("hydrostatic.toml");
        scene.simulation.wall_rows = rows;
        let (d, rho, g) = (scene.simulation.particle_spacing, scene.phases[0].density, -scene.simulation.gravity[1]);
        // The fill's top and the container's side in scenes/hydrostatic.toml.
        let (fill, side) = (0.3f32, 0.1f32);
        let mut sim = Simulation::new(scene);
        // Sums of p and rho g depth by the number of walls within d.
        let mut sums = [[0.0f64; 2]; 4];
        while sim.step < 100 {
            sim.step().unwrap_or_else(|e| panic!("{e}"));
            if sim.step <= 50 {
                continue;
            }
            let f = &sim.fluid;
            for i in (0..f.len()).filter(|&i| f.y[i] < fill - 3.0 * d) {
                let near = |c: f32| usize::from(c < d) + usize::from(c > side - d);
                let walls = near(f.x[i]) + near(f.z[i]) + usize::from(f.y[i] < d);
                sums[walls.min(3)][0] += f64::from(f.pressure[i]);
                sums[walls.min(3)][1] += f64::from(rho * g * (fill - f.y[i]));
            }
        }
        let ratio = sums.map(|[p, r]| p / r);
        println!(
            "wall_rows {rows:?}: p / rho g depth over steps 51-100, by walls within d: none {:.3}, one {:.3}, \
             two (edges) {:.3}, three (corners) {:.3}",
            ratio[0], ratio[1], ratio[2], ratio[3]
        );
        ratio
    };
    run(WallRowsChoice::Akinci);
    let lattice = run(WallRowsChoice::Lattice);
    for (name, r) in [("edges", lattice[2]), ("corners", lattice[3])] {
        assert!((r - 1.0).abs() < 0.1, "{name}: p / rho g depth {r:.3}");
    }
}

/// What [`tank_at_rest_per_particle`] measures at one time.
struct AtRest {
    /// RMS and median speed of the fluid particles, m/s.
    rms: f64,
    median: f64,
    /// Mean over the particles deeper than 2.5 d of |p - rho g depth| /
    /// (rho g H), per particle.
    pressure_error: f64,
    /// The least-squares slope of p against y over the same particles,
    /// relative to -rho g, minus 1.
    slope_error: f64,
    /// Drop of the fluid's centre of mass since the start, m.
    settled: f64,
}

fn at_rest(sim: &Simulation, fill: f64, d: f64, y_start: f64) -> AtRest {
    let f = &sim.fluid;
    let n = f.len();
    let mut speed: Vec<f64> =
        (0..n).map(|i| f64::from(f.ux[i] * f.ux[i] + f.uy[i] * f.uy[i] + f.uz[i] * f.uz[i]).sqrt()).collect();
    let rms = (speed.iter().map(|s| s * s).sum::<f64>() / n as f64).sqrt();
    speed.sort_by(f64::total_cmp);
    let rho_g = 1000.0 * 9.81;
    let deep: Vec<(f64, f64)> =
        (0..n).map(|i| (f64::from(f.y[i]), f64::from(f.pressure[i]))).filter(|&(y, _)| y < fill - 2.5 * d).collect();
    let m = deep.len() as f64;
    let pressure_error = deep.iter().map(|&(y, p)| (p - rho_g * (fill - y)).abs()).sum::<f64>() / m / (rho_g * fill);
    let (sy, sp) = deep.iter().fold((0.0, 0.0), |(a, b), &(y, p)| (a + y, b + p));
    let (my, mp) = (sy / m, sp / m);
    let (cov, var) = deep.iter().fold((0.0, 0.0), |(c, v), &(y, p)| (c + (y - my) * (p - mp), v + (y - my) * (y - my)));
    let y_mean = f.y.iter().map(|&y| f64::from(y)).sum::<f64>() / n as f64;
    AtRest {
        rms,
        median: speed[n / 2],
        pressure_error,
        slope_error: -(cov / var) / rho_g - 1.0,
        settled: y_start - y_mean,
    }
}

/// The solver-accuracy issue's tank at rest, measured per particle: 0.3 x
/// 0.3 (high) x 0.12 m of water at d = 1 cm in a closed tank with 0.1 m of
/// headroom, mu 0.01 Pa s, max_dt 2 ms, 0.1 % density error, from the
/// lattice start. Asked (the issue): RMS speed <= 5 mm/s at 1 s and
/// <= 1 mm/s at 3 s; the per-particle pressure error <= 2 % at 1 s and the
/// slope of p against depth within 1 % of rho g. Reference: hydrostatics,
/// p = rho g (H - y) with H the fill height.
///
/// FAILS today (2026-12-02): RMS 0.052 m/s at 1 s and 0.028 m/s at 3 s,
/// pressure error 6.5 % and 4.3 %, slope +2.2 % and +2.3 % off (+0.1 % at 2
/// s: it wanders with the motion). What the motion does not come from, each
/// measured with this set-up up to 0.5-1 s: the solver's tolerance (RMS
/// 0.065 m/s at 0.5 s at 1e-3, 1e-4 and 1e-5, the last with 500 iterations
/// per step and converged), the time step (0.5 ms: 0.066), the start-up
/// (pressure initialised to rho g depth, or 200 steps with the velocities
/// zeroed each step before the clock starts: 0.065 and 0.060 m/s 0.1 s
/// later), the free surface (the tank filled to its lid: 0.060 / 0.052 m/s
/// at 0.1 / 1 s). Where the energy comes from: the fluid's centre of mass
/// drops 0.62 mm in the first 0.1 s and 0.90 mm by 1 s, releasing 6.1e-3
/// and 8.8e-3 J/kg, three to six times the kinetic energy then (1.8e-3,
/// 1.3e-3 J/kg); with 1 Pa s, which damps the motion (4.9 mm/s at 1 s), it
/// still drops 1.03 mm. So the column settles into a denser state whatever
/// the solver does, and mostly in its bulk, not at its walls: in a box 0.05
/// m from the floor, the surface and the x walls and 0.03 m from the z
/// walls the number of particles grows by 0.67 % by 1 s (2400 to 2416)
/// while their SPH density stays at 1001.08 kg/m^3 (0.108 %, the
/// tolerance); the layer next to each wall moves only 0.04-0.18 mm closer
/// to it. In a tank twice as wide and twice as long (0.6 x 0.3 x 0.24 m)
/// the walls' layers move 0.02-0.09 mm, the core's count grows by 0.50 % by
/// 0.5 s (18000 to 18090) at 1001.11 kg/m^3, the centre of mass drops 0.65
/// mm, and the RMS speed is the same, 0.062 m/s at 0.5 s. So the fluid
/// packs 0.5-0.7 % denser at the same SPH density, and the potential energy
/// the column releases is the motion. Why it can, in part: at the same
/// number density an FCC packing's kernel sum is 0.25 % below the cubic
/// lattice's (BCC 0.02 %; `scripts/kernel_sums.py`), so a rearrangement
/// from the start lattice towards close packing lets the density rule hold
/// more particles per volume (uncorrelated jitter does the opposite: +0.65
/// % at 0.05 d RMS); that is about half of what is measured, the rest is
/// not yet accounted for.
///
/// Measured 2026-12-02 (second session): the motion is made anew every
/// step, not only released once. Run 1 or 2 s, set every velocity to zero
/// and go on: the RMS speed is back at 0.009 m/s after one step, 0.033 m/s
/// after five (10 ms) while the centre of mass drops only 0.026-0.05 mm. In
/// that one step from rest, the interior particles (3 d from walls and
/// surface, 3416 of them) take a net acceleration of 4.97 m/s^2 RMS (0.5
/// g; 5.84 below y = 0.08 m, so it grows with depth). Split per particle,
/// a_p = -sum_j m (p_i/rho^2 + p_j/rho^2) grad W_ij = -(2 p_i/rho0) sum_j
/// V_j grad W_ij - (1/rho0) sum_j V_j (p_j - p_i) grad W_ij: the first,
/// zeroth-order term is 5.29 m/s^2 RMS and correlates 0.73 with the net
/// acceleration; the second misses g by 3.9 m/s^2 RMS; what the two do
/// not explain is 0.70 m/s^2. So the root is the symmetric pressure
/// gradient in a disordered packing: sum_j V_j grad W_ij is about 1.8 % of
/// 1/d there, and times a pressure of rho g depth it is half of g. On the
/// start lattice that sum is zero, but no lattice holds: a linear model of
/// the kernel sum's second variation on density-preserving Bloch modes (H
/// = 2d; `scripts/lattice_stability.py`) has negative curvature for the
/// cubic, BCC and FCC lattices, so pressure drives any of them to a
/// disordered packing (the measured compaction) and keeps its particles
/// moving. Not a cure, each measured
/// here: a larger support (H = 2.2 d: RMS 0.073 m/s at 1 s; 2.4 d: 0.060),
/// a tighter solve after the fact (switching 1e-3 to 1e-4 or 1e-5 at 1 s
/// removes the 0.11 % compression in one step at 0.10 m/s and overshoots
/// to 0.27 % expansion, which the one-sided stop criterion and p >= 0 do
/// not see). A particle shift along -sum_j V_j grad W_ij (fluid and wall
/// volumes, not within 2.5 d of the surface), applied outside the step at
/// 0.1 d^2 per step, halves the motion (0.032 / 0.019 m/s at 0.5 / 1 s);
/// 0.2 d^2 does no better, 0.5 d^2 and more blow up. Next: a pressure
/// gradient without the zeroth-order error (the difference form with a
/// kernel-gradient correction, which gives up pairwise momentum
/// conservation) or particle shifting inside the step, each measured
/// against this test and the conservation tests.
/// With `pressure_warm_start = "hydrostatic"` (kernels/src/hydrostatic.rs,
/// measured 2026-12-05; the half warm start's in brackets): RMS speed
/// 0.064 / 0.052 / 0.038 / 0.029 m/s at 0.5 / 1 / 2 / 3 s (0.062 / 0.052
/// / 0.038 / 0.028), pressure error per particle 8.6 / 4.5 / 3.4 / 2.9 %
/// (7.4 / 6.5 / - / 4.4 %), slope +11 / -0.7 / +1.7 / +2.4 % off rho g.
/// The pressure is nearer rho g depth, the motion the same: it is not made
/// by the solve's start.
#[test]
#[ignore = "fails today (see its doc): 3 s of a 10.8k-particle tank, about 2 min on 2 cores"]
fn tank_at_rest_per_particle() {
    tank_at_rest("cubic_spline");
}

/// The same tank with `kernel = "wendland_c2"` (kernels/src/kernel.rs):
/// Wendland C2 at H = 2d, its lattice sum and gradient calibrated on the
/// start lattice. Its cubic lattice has no unstable density-preserving
/// mode at positive pressure (`scripts/lattice_stability.py --kernel
/// wendland`: least curvature +1.0e-3, against the spline's -2.65e-1).
///
/// FAILS the bounds too, but moves about three times less
/// (2026-12-03): RMS 0.021 / 0.018 / 0.013 / 0.010 m/s at 0.5 / 1 / 2 / 3 s
/// (the spline: 0.062 / 0.052 / 0.038 / 0.028), pressure error per
/// particle 4.0 / 4.0 / 3.5 / 3.4 % (the spline: 7.4 / 6.5 / 4.4 % at 0.5 /
/// 1 / 3 s), slope 1.3-2.6 % off rho g (it wanders with the motion), the centre of mass settling 0.40 mm by 0.5 s (0.62 mm by 0.1
/// s with the spline). The motion is still made anew each step, but
/// slower: zeroing every velocity at 1 s, the RMS speed is 0.0047 m/s
/// after one step and 0.012 after five (the spline: 0.009 and 0.033). Most
/// of it comes in the start-up: 0.023 m/s at 0.1 s. Also measured, not
/// kept: a cold start of each solve (warm start 0 instead of 0.5) gives
/// 0.0135 m/s at 1 s for 51 instead of 26 iterations per step; a warm start
/// of 0.9 or 1.0 gives 0.13-0.18 m/s; a tolerance of 1e-4, 0.0156 m/s.
/// Measured 2026-12-05 (commit 6d78fb6): a two-sided stop criterion (the
/// error of a row with p > 0 counted as |residual|, expansion too, not
/// only compression; fluid and solid rows) does not rescue the full warm
/// start: warm start 1.0 one-sided 0.177 m/s at 1 s and 24.2 % pressure
/// error, two-sided 0.136 m/s and 19.4 % (in 36 s against 53 s: still far
/// fewer iterations); with the 0.5 warm start the criterion changes
/// nothing (0.0177 against 0.0174 m/s). The full warm start's appeal is
/// its cost: Example 1 at d = 5 mm runs 4.3 instead of 17.9 Jacobi
/// iterations per step with it (fluid only, 0.022 against 0.077 s/step);
/// a deep pool's solve spends most of its sweeps rebuilding the half of
/// the hydrostatic pressure the 0.5 warm start drops.
/// With `pressure_warm_start = "hydrostatic"` (measured 2026-12-05): RMS
/// 0.017 / 0.013 / 0.011 / 0.008 m/s at 0.5 / 1 / 2 / 3 s (the half warm
/// start: 0.021 / 0.018 / 0.013 / 0.010), pressure error per particle 2.3 /
/// 2.3 / 1.5 / 1.9 % (4.0 / 4.0 / 3.5 / 3.4 %).
/// With `wall_rows = "lattice"` (measured 2026-12-06 with the half warm
/// start; this test without it, the same day, in brackets): RMS 0.0136 / 0.0121 /
/// 0.0093 / 0.0074 m/s at 0.5 / 1 / 2 / 3 s (0.0199 / 0.0168 / 0.0126 /
/// 0.0099), pressure error per particle 2.2 / 1.6 / 1.8 / 1.2 % (4.5 /
/// 3.9 / 3.5 / 3.6 %), slope -3.8 / +0.9 / -3.3 / -0.3 % off rho g: the
/// issue's pressure and slope bounds hold at 1 s, its speed bounds do not
/// (bench/RESULTS.md, "The container's edges and corners").
#[test]
#[ignore = "fails today (see its doc): 3 s of a 10.8k-particle tank, about 1 min on 2 cores"]
fn tank_at_rest_per_particle_wendland() {
    tank_at_rest("wendland_c2");
}

/// Runs the tank of [`tank_at_rest_per_particle`] with `kernel` for 3 s and
/// checks the bounds.
fn tank_at_rest(kernel: &str) {
    let (d, fill) = (0.01f64, 0.3f64);
    let scene = format!(
        "[simulation]\nparticle_spacing = 0.01\nend_time = 3.0\nmax_dt = 0.002\nmax_density_error = 0.001\n\
         kernel = \"{kernel}\"\n\
         [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 0.01\n\
         [[fluid]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.3, 0.12] }}\nfractions = {{ water = 1.0 }}\n\
         [[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.4, 0.12] }}\ncontainer = true\n"
    );
    let mut sim = Simulation::new(common::scene_text(&scene));
    let y_start = sim.fluid.y.iter().map(|&y| f64::from(y)).sum::<f64>() / sim.fluid.len() as f64;
    let mut seen = Vec::new();
    for t in [0.5, 1.0, 2.0, 3.0] {
        common::run_until(&mut sim, t);
        let r = at_rest(&sim, fill, d, y_start);
        println!(
            "tank at rest ({kernel}), t = {t} s: RMS speed {:.4} m/s (median {:.4}), pressure error per particle {:.2} %, \
             slope {:+.2} % off rho g, centre of mass settled {:.3} mm",
            r.rms,
            r.median,
            100.0 * r.pressure_error,
            100.0 * r.slope_error,
            1e3 * r.settled
        );
        seen.push((t, r));
    }
    let at = |t: f64| &seen.iter().find(|(s, _)| *s == t).expect("sampled").1;
    assert!(at(1.0).rms <= 5e-3 && at(3.0).rms <= 1e-3, "RMS speed {:.4} / {:.4} m/s", at(1.0).rms, at(3.0).rms);
    assert!(at(1.0).pressure_error <= 0.02 && at(1.0).slope_error.abs() <= 0.01);
}

/// `max_row_density_error` (the solve's bound on every row, not only the
/// mean): Example 1 (scenes/example1_wave_block.toml, d = 1 cm) with the
/// hydrostatic warm start, 0.2 s. Without the bound some solves stop on
/// their mean error with a row compressed by more than 2 % (the column's
/// foot and the block's contact rows, bench/RESULTS.md); with
/// `max_row_density_error = 0.02` every solve that stops below its sweep
/// cap has every fluid and solid row within 2 %, and the mean criterion
/// still holds.
#[test]
fn the_row_bound_holds_every_row_of_every_solve() {
    let run = |bound: Option<f32>| {
        let mut scene = common::scene_file("example1_wave_block.toml");
        scene.simulation.pressure_warm_start = PressureWarmStart::Hydrostatic;
        scene.simulation.max_row_density_error = bound;
        let (target, cap) = (scene.simulation.max_density_error, scene.simulation.max_iterations);
        let mut sim = Simulation::new(scene);
        let (mut above, mut worst, mut steps, mut sweeps) = (0usize, 0.0f32, 0usize, 0u64);
        while sim.time < 0.2 {
            let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
            steps += 1;
            sweeps += u64::from(st.iterations);
            if st.iterations < cap {
                assert!(st.density_error <= target && st.solid_density_error <= target);
                worst = worst.max(st.largest_density_error);
                above += (st.largest_density_error > 0.02) as usize;
            }
        }
        println!(
            "row bound {bound:?}: {steps} steps, {sweeps} sweeps; {above} solves ended with a row above 2 %, largest {worst:.4}"
        );
        (above, worst)
    };
    let (above_free, _) = run(None);
    let (above, worst) = run(Some(0.02));
    assert!(above_free > 0, "without the bound no solve ends with a row above 2 %: the test shows nothing");
    assert_eq!(above, 0, "largest row error {worst}");
}
