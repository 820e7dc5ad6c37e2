//! Sampling scenes into particles: counts, spacing, and the signed distances
//! the sampling is built on. Expected counts are computed by hand from the
//! lattice rules documented in `scene::geometry`.

use porosph::scene::{sample_fluid, sample_walls, sdf, Scene, Shape};

const D: f32 = 0.01;

/// A scene with one phase, spacing `D`, and the given `[[fluid]]`/`[[wall]]` text.
fn scene(body: &str) -> Scene {
    let text = format!(
        "[simulation]\nparticle_spacing = {D}\nend_time = 1.0\nmax_dt = 0.001\n\
         [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 0.001\n{body}"
    );
    Scene::from_toml_str(&text, "<test>").unwrap_or_else(|e| panic!("{e}"))
}

fn dist2(a: [f32; 3], b: [f32; 3]) -> f64 {
    (0..3).map(|i| (f64::from(a[i]) - f64::from(b[i])).powi(2)).sum()
}

/// Smallest distance between a point of `a` and a point of `b` (brute force).
fn min_distance(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let mut best = f64::INFINITY;
    for &p in a {
        for &q in b {
            best = best.min(dist2(p, q));
        }
    }
    best.sqrt()
}

/// Smallest distance between two distinct points of `a` (brute force).
fn min_self_distance(a: &[[f32; 3]]) -> f64 {
    let mut best = f64::INFINITY;
    for (i, &p) in a.iter().enumerate() {
        for &q in &a[i + 1..] {
            best = best.min(dist2(p, q));
        }
    }
    best.sqrt()
}

#[test]
fn fluid_box_count_is_the_lattice_count() {
    let s = scene(
        "[[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.2, 0.4, 0.1] }\n\
         fractions = { water = 1.0 }\nvelocity = [1.0, 2.0, 3.0]\n",
    );
    let walls = sample_walls(&s);
    let fluid = sample_fluid(&s, &walls);
    assert!(walls.positions.is_empty());
    assert_eq!(fluid.positions.len(), 20 * 40 * 10);
    assert_eq!(fluid.velocities.len(), 8000);
    assert_eq!(fluid.fractions.len(), 8000);
    assert!(fluid.velocities.iter().all(|v| *v == [1.0, 2.0, 3.0]));
    assert!(fluid.fractions.iter().all(|f| *f == vec![1.0]));
    // Lattice order: x fastest, then y, then z; first point half a spacing in.
    let p0 = fluid.positions[0];
    let p1 = fluid.positions[1];
    let p20 = fluid.positions[20];
    let p800 = fluid.positions[800];
    let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
    assert!(close(p0[0], 0.005) && close(p0[1], 0.005) && close(p0[2], 0.005));
    assert!(close(p1[0], 0.015) && close(p1[1], 0.005));
    assert!(close(p20[0], 0.005) && close(p20[1], 0.015));
    assert!(close(p800[1], 0.005) && close(p800[2], 0.015));
}

#[test]
fn box_that_is_not_a_multiple_of_the_spacing_is_snapped() {
    // 0.104 / 0.01 = 10.4 -> 10 cells; 0.056 / 0.01 = 5.6 -> 6 cells.
    let s = scene(
        "[[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.104, 0.056, 0.01] }\n\
         fractions = { water = 1.0 }\n",
    );
    let fluid = sample_fluid(&s, &sample_walls(&s));
    assert_eq!(fluid.positions.len(), 10 * 6);
}

/// Wall particles of a container with n cells per axis: the (n+4)^3 lattice
/// block minus the n^3 interior; with an open top, the y range ends at n - 1
/// instead of n + 1.
fn container_count(n: [usize; 3], open_top: bool) -> usize {
    let ny = if open_top { n[1] + 2 } else { n[1] + 4 };
    (n[0] + 4) * ny * (n[2] + 4) - n[0] * n[1] * n[2]
}

#[test]
fn container_wall_count_closed_and_open_top() {
    let body = |open: bool| {
        format!(
            "[[wall]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.05, 0.03, 0.04] }}\n\
             container = true\nopen_top = {open}\n"
        )
    };
    let closed = sample_walls(&scene(&body(false)));
    assert_eq!(closed.positions.len(), container_count([5, 3, 4], false));
    assert_eq!(closed.positions.len(), 9 * 7 * 8 - 5 * 3 * 4);

    let open = sample_walls(&scene(&body(true)));
    assert_eq!(open.positions.len(), container_count([5, 3, 4], true));
    assert!(open.positions.iter().all(|p| p[1] < 0.03));

    // Every wall particle lies outside the box, and within two layers of it.
    let boxed = Shape::Box { min: [0.0, 0.0, 0.0], max: [0.05, 0.03, 0.04] };
    for &p in &closed.positions {
        let s = sdf(&boxed, p);
        assert!(s > 0.0 && s < 2.5 * D * 3f32.sqrt(), "{p:?}: {s}");
    }
}

#[test]
fn fluid_filling_its_container_keeps_one_spacing_from_the_wall() {
    let s = scene(
        "[[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.08, 0.05] }\n\
         fractions = { water = 1.0 }\n\
         [[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.08, 0.05] }\ncontainer = true\n",
    );
    let walls = sample_walls(&s);
    let fluid = sample_fluid(&s, &walls);
    assert_eq!(fluid.positions.len(), 10 * 8 * 5, "no fluid is dropped");
    let d = f64::from(D);
    let gap = min_distance(&fluid.positions, &walls.positions);
    assert!(gap >= d * (1.0 - 1e-4), "fluid-wall gap {gap}");
    assert!(gap <= d * (1.0 + 1e-4), "fluid-wall gap {gap}");
}

#[test]
fn sphere_count_matches_its_volume() {
    // The number of lattice points in a ball of radius r = 10 d approaches
    // 4/3 pi r^3 / d^3 = 4188.8; the surface error is well within 2 %.
    let expected = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
    for center in ["[0.0, 0.0, 0.0]", "[0.005, 0.005, 0.005]", "[0.0123, -0.0371, 0.2]"] {
        let s = scene(&format!(
            "[[fluid]]\nsphere = {{ center = {center}, radius = 0.1 }}\nfractions = {{ water = 1.0 }}\n"
        ));
        let n = sample_fluid(&s, &sample_walls(&s)).positions.len() as f64;
        assert!((n - expected).abs() / expected < 0.02, "centre {center}: {n} points, expected about {expected}");
    }
}

#[test]
fn cylinder_count_matches_its_volume() {
    // pi r^2 h / d^3 with r = 8 d, h = 20 d: 4021.2 points, within 2 %. The
    // base is off the lattice: a cap plane through a lattice plane would count
    // its points whole rather than half (+3.5 % here).
    let expected = std::f64::consts::PI * 64.0 * 20.0;
    let s = scene(
        "[[fluid]]\ncylinder = { base = [0.0013, 0.0007, 0.0031], axis = [1.0, 1.0, 0.0], radius = 0.08, height = 0.2 }\n\
         fractions = { water = 1.0 }\n",
    );
    let n = sample_fluid(&s, &sample_walls(&s)).positions.len() as f64;
    assert!((n - expected).abs() / expected < 0.02, "{n} points, expected about {expected}");
}

#[test]
fn solid_walls_are_two_layer_shells() {
    // Solid box of 6 x 5 x 4 cells: all but the interior 2 x 1 x 0 block.
    let s = scene("[[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.06, 0.05, 0.04] }\n");
    assert_eq!(sample_walls(&s).positions.len(), 6 * 5 * 4);
    let s = scene("[[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.08, 0.07, 0.06] }\n");
    assert_eq!(sample_walls(&s).positions.len(), 8 * 7 * 6 - 4 * 3 * 2);

    // Solid sphere of radius 10 d: the shell volume 4/3 pi (r^3 - (r - 2d)^3).
    let s = scene("[[wall]]\nsphere = { center = [0.0, 0.0, 0.0], radius = 0.1 }\n");
    let shell = Shape::Sphere { center: [0.0; 3], radius: 0.1 };
    let walls = sample_walls(&s);
    for &p in &walls.positions {
        let dist = sdf(&shell, p);
        assert!(dist > -2.0 * D && dist <= 0.0, "{p:?}: {dist}");
    }
    let expected = 4.0 / 3.0 * std::f64::consts::PI * (1000.0 - 512.0);
    let n = walls.positions.len() as f64;
    assert!((n - expected).abs() / expected < 0.03, "{n}, expected about {expected}");
}

#[test]
fn fluid_is_kept_out_of_solid_obstacles() {
    // A fluid box around a solid sphere: no fluid inside the sphere, even in its
    // core where the two-layer shell has no particles.
    let s = scene(
        "[[fluid]]\nbox = { min = [-0.2, -0.2, -0.2], max = [0.2, 0.2, 0.2] }\n\
         fractions = { water = 1.0 }\n\
         [[wall]]\nsphere = { center = [0.0, 0.0, 0.0], radius = 0.1 }\n",
    );
    let walls = sample_walls(&s);
    let fluid = sample_fluid(&s, &walls);
    let ball = &s.walls[0].shape;
    assert!(fluid.positions.iter().all(|&p| sdf(ball, p) > 0.0));
    assert!(min_distance(&fluid.positions, &walls.positions) >= 0.5 * f64::from(D));
    assert!(fluid.positions.len() < 40 * 40 * 40);
}

#[test]
fn overlapping_shapes_never_put_particles_closer_than_half_a_spacing() {
    let s = scene(
        "[[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1] }\n\
         fractions = { water = 1.0 }\n\
         [[fluid]]\nsphere = { center = [0.1, 0.1, 0.05], radius = 0.06 }\n\
         fractions = { water = 1.0 }\nvelocity = [0.0, -1.0, 0.0]\n\
         [[fluid]]\nbox = { min = [0.0033, 0.0033, 0.0033], max = [0.0733, 0.0733, 0.0733] }\n\
         fractions = { water = 1.0 }\n\
         [[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.2, 0.2, 0.1] }\ncontainer = true\n\
         [[wall]]\nbox = { min = [-0.017, -0.017, -0.017], max = [0.1, 0.1, 0.05] }\ncontainer = true\n\
         [[wall]]\ncylinder = { base = [0.15, 0.0, 0.05], axis = [0.0, 1.0, 0.0], radius = 0.03, height = 0.1 }\n",
    );
    let walls = sample_walls(&s);
    let fluid = sample_fluid(&s, &walls);
    assert!(!fluid.positions.is_empty());
    let mut all = walls.positions.clone();
    all.extend_from_slice(&fluid.positions);
    let gap = min_self_distance(&all);
    assert!(gap >= 0.5 * f64::from(D), "closest pair {gap}");
}

#[test]
fn a_block_inside_an_earlier_block_adds_nothing() {
    // The second block's lattice is offset by 0.2 d on each axis, so each of
    // its points is 0.35 d from a point of the first block and is dropped.
    let s = scene(
        "[[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1] }\n\
         fractions = { water = 1.0 }\n\
         [[fluid]]\nbox = { min = [0.002, 0.002, 0.002], max = [0.072, 0.072, 0.072] }\n\
         fractions = { water = 1.0 }\nvelocity = [0.0, -1.0, 0.0]\n",
    );
    let fluid = sample_fluid(&s, &sample_walls(&s));
    assert_eq!(fluid.positions.len(), 10 * 10 * 10);
    assert!(fluid.velocities.iter().all(|v| *v == [0.0; 3]));
}

#[test]
fn sampling_is_deterministic() {
    let s = scene(
        "[[fluid]]\nsphere = { center = [0.03, 0.04, 0.05], radius = 0.05 }\nfractions = { water = 1.0 }\n\
         [[wall]]\ncylinder = { base = [0.0, -0.05, 0.0], axis = [0.0, 0.0, 1.0], radius = 0.03, height = 0.1 }\n",
    );
    let (w1, w2) = (sample_walls(&s), sample_walls(&s));
    assert_eq!(w1.positions, w2.positions);
    assert_eq!(sample_fluid(&s, &w1).positions, sample_fluid(&s, &w2).positions);
}

#[test]
fn signed_distances_are_exact() {
    let tol = 1e-6;
    let cube = Shape::Box { min: [0.0, 0.0, 0.0], max: [1.0, 2.0, 3.0] };
    assert!((sdf(&cube, [0.5, 1.0, 1.5]) + 0.5).abs() < tol, "centre: nearest face x");
    assert!((sdf(&cube, [2.0, 1.0, 1.0]) - 1.0).abs() < tol, "outside a face");
    assert!((sdf(&cube, [2.0, 3.0, 1.0]) - 2f32.sqrt()).abs() < tol, "outside an edge");
    assert!((sdf(&cube, [-1.0, -1.0, -1.0]) - 3f32.sqrt()).abs() < tol, "outside a corner");

    let ball = Shape::Sphere { center: [1.0, 1.0, 1.0], radius: 0.5 };
    assert!((sdf(&ball, [1.0, 1.0, 1.0]) + 0.5).abs() < tol);
    assert!((sdf(&ball, [1.0, 3.0, 1.0]) - 1.5).abs() < tol);

    let can = Shape::Cylinder { base: [0.0, 0.0, 0.0], axis: [0.0, 0.0, 1.0], radius: 1.0, height: 2.0 };
    assert!((sdf(&can, [0.0, 0.0, 1.0]) + 1.0).abs() < tol, "centre");
    assert!((sdf(&can, [0.0, 0.2, 1.9]) + 0.1).abs() < tol, "near the top cap");
    assert!((sdf(&can, [0.9, 0.0, 1.0]) + 0.1).abs() < tol, "near the side");
    assert!((sdf(&can, [3.0, 0.0, 1.0]) - 2.0).abs() < tol, "beside the side");
    assert!((sdf(&can, [0.0, 0.5, -2.0]) - 2.0).abs() < tol, "below the base");
    assert!((sdf(&can, [0.0, 4.0, 6.0]) - 5.0).abs() < tol, "beyond the rim: 3-4-5");
}
