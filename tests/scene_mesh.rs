//! Mesh shapes (`mesh = { path, scale, translate }`): OBJ and STL (ASCII
//! and binary) read, filled on the global lattice like spheres and
//! cylinders, walls as two-layer shells; a closed cube gives exactly the
//! particles of the same `box`, an icosphere those of the `sphere` to
//! within the polyhedron's missing volume; bad meshes are errors that name
//! the file and the reason.

use porosph::scene::{sample_fluid, sample_solids, sample_walls, sdf, Scene, SceneError};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A scratch directory, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("porosph-mesh-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

const HEADER: &str = "[simulation]\nparticle_spacing = 0.01\nend_time = 1.0\nmax_dt = 0.001\n\
                      [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 0.001\n";

fn scene(body: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_str(&format!("{HEADER}{body}"), "test.toml")
}

fn parsed(body: &str) -> Scene {
    scene(body).unwrap_or_else(|e| panic!("{e}"))
}

/// A triangle mesh: vertices and counter-clockwise (seen from outside)
/// triangles.
struct Mesh {
    v: Vec<[f64; 3]>,
    t: Vec<[usize; 3]>,
}

/// The box [lo, hi] as 12 outward triangles.
fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
    let v = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        })
        .collect();
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let t = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    Mesh { v, t }
}

/// An icosahedron subdivided `levels` times, on the sphere of `radius`
/// about `center`.
fn icosphere(center: [f64; 3], radius: f64, levels: usize) -> Mesh {
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, p, 0.0],
        [1.0, p, 0.0],
        [-1.0, -p, 0.0],
        [1.0, -p, 0.0],
        [0.0, -1.0, p],
        [0.0, 1.0, p],
        [0.0, -1.0, -p],
        [0.0, 1.0, -p],
        [p, 0.0, -1.0],
        [p, 0.0, 1.0],
        [-p, 0.0, -1.0],
        [-p, 0.0, 1.0],
    ];
    let mut t: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let unit = |a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|c| c / n)
    };
    v.iter_mut().for_each(|a| *a = unit(*a));
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for tri in &t {
            let mut m = [0; 3];
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                m[e] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push(unit([0, 1, 2].map(|k| (v[a][k] + v[b][k]) / 2.0)));
                    v.len() - 1
                });
            }
            next.extend([[tri[0], m[0], m[2]], [tri[1], m[1], m[0]], [tri[2], m[2], m[1]], [m[0], m[1], m[2]]]);
        }
        t = next;
    }
    let v = v.iter().map(|a| [0, 1, 2].map(|k| center[k] + radius * a[k])).collect();
    Mesh { v, t }
}

impl Mesh {
    fn corners(&self, tri: &[usize; 3]) -> [[f32; 3]; 3] {
        tri.map(|i| self.v[i].map(|c| c as f32))
    }

    /// Wavefront OBJ text (1-based indices).
    fn obj(&self) -> String {
        let mut s = String::from("# porosph test mesh\no cube\n");
        for p in &self.v {
            let _ = writeln!(s, "v {} {} {}", p[0] as f32, p[1] as f32, p[2] as f32);
        }
        for tri in &self.t {
            let _ = writeln!(s, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1);
        }
        s
    }

    /// ASCII STL text.
    fn stl_ascii(&self) -> String {
        let mut s = String::from("solid test\n");
        for tri in &self.t {
            s.push_str("  facet normal 0 0 0\n    outer loop\n");
            for c in self.corners(tri) {
                let _ = writeln!(s, "      vertex {} {} {}", c[0], c[1], c[2]);
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        s.push_str("endsolid test\n");
        s
    }

    /// Binary STL bytes.
    fn stl_binary(&self) -> Vec<u8> {
        let mut b = vec![b' '; 80];
        b[..11].copy_from_slice(b"porosph bin");
        b.extend((self.t.len() as u32).to_le_bytes());
        for tri in &self.t {
            b.extend([0f32; 3].iter().flat_map(|x| x.to_le_bytes()));
            for c in self.corners(tri) {
                b.extend(c.iter().flat_map(|x| x.to_le_bytes()));
            }
            b.extend(0u16.to_le_bytes());
        }
        b
    }

    /// Writes the mesh as `name` (format by extension; `.bin.stl` binary).
    fn write(&self, dir: &TempDir, name: &str) -> PathBuf {
        let path = dir.path(name);
        let bytes = if name.ends_with(".obj") {
            self.obj().into_bytes()
        } else if name.ends_with(".bin.stl") {
            self.stl_binary()
        } else {
            self.stl_ascii().into_bytes()
        };
        std::fs::write(&path, bytes).expect("write mesh");
        path
    }
}

fn toml_path(p: &Path) -> String {
    format!("{:?}", p.display().to_string())
}

#[test]
fn obj_and_stl_cubes_fill_exactly_like_the_box() {
    let dir = TempDir::new("cube");
    let (lo, hi) = ([0.0, 0.0, 0.0], [0.2, 0.1, 0.15]);
    let cube = cuboid(lo, hi);
    let boxed =
        parsed("[[fluid]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.2, 0.1, 0.15] }\nfractions = { water = 1.0 }\n");
    let want = sample_fluid(&boxed, &sample_walls(&boxed)).positions;
    assert_eq!(want.len(), 20 * 10 * 15);
    for name in ["cube.obj", "cube.stl", "cube.bin.stl"] {
        let path = cube.write(&dir, name);
        let s =
            parsed(&format!("[[fluid]]\nmesh = {{ path = {} }}\nfractions = {{ water = 1.0 }}\n", toml_path(&path)));
        let got = sample_fluid(&s, &sample_walls(&s)).positions;
        assert_eq!(got, want, "{name}: not the box's particles");

        // As a solid, too.
        let solid = |shape: &str| {
            parsed(&format!(
                "[[solid]]\nname = \"s\"\n{shape}\ndensity = 500.0\nshear_modulus = 1e4\nlame_lambda = 1e4\n"
            ))
        };
        let a = solid("box = { min = [0.0, 0.0, 0.0], max = [0.2, 0.1, 0.15] }");
        let b = solid(&format!("mesh = {{ path = {} }}", toml_path(&path)));
        assert_eq!(sample_solids(&b, &sample_walls(&b)).positions, sample_solids(&a, &sample_walls(&a)).positions);

        // As a wall: the two-layer shell of the box wall.
        let a = parsed("[[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.2, 0.1, 0.15] }\n");
        let b = parsed(&format!("[[wall]]\nmesh = {{ path = {} }}\n", toml_path(&path)));
        assert_eq!(sample_walls(&b).positions, sample_walls(&a).positions, "{name}: wall");
    }
}

#[test]
fn a_scaled_and_moved_cube_fills_its_box_off_the_origin() {
    // A unit cube scaled to 0.2 m and moved to a corner at (0.1, 0.05,
    // 0.02): the box with that corner holds the same lattice points, up to
    // the rounding of `min + (i + 1/2) d` against `(i + 1/2) d` in f32.
    let dir = TempDir::new("moved");
    let path = cuboid([0.0; 3], [1.0, 0.5, 0.5]).write(&dir, "unit.obj");
    let boxed =
        parsed("[[fluid]]\nbox = { min = [0.1, 0.05, 0.02], max = [0.3, 0.15, 0.12] }\nfractions = { water = 1.0 }\n");
    let want = sample_fluid(&boxed, &sample_walls(&boxed)).positions;
    let s = parsed(&format!(
        "[[fluid]]\nmesh = {{ path = {}, scale = 0.2, translate = [0.1, 0.05, 0.02] }}\nfractions = {{ water = 1.0 }}\n",
        toml_path(&path)
    ));
    let got = sample_fluid(&s, &sample_walls(&s)).positions;
    assert_eq!(got.len(), want.len());
    assert_eq!(got.len(), 20 * 10 * 10);
    for (a, b) in got.iter().zip(&want) {
        assert!((0..3).all(|k| (a[k] - b[k]).abs() <= 1e-7), "{a:?} vs {b:?}");
    }
}

#[test]
fn an_icosphere_fills_like_the_sphere() {
    // Level 5: 20480 triangles, whose polyhedron misses about 0.05 % of
    // the ball's volume; the lattice counts agree within 0.5 %.
    let dir = TempDir::new("ico");
    let (center, radius) = ([0.0123, -0.0371, 0.2], 0.1);
    let ico = icosphere(center, radius, 5);
    assert_eq!(ico.t.len(), 20480);
    let path = ico.write(&dir, "ico.bin.stl");
    let ball =
        parsed("[[fluid]]\nsphere = { center = [0.0123, -0.0371, 0.2], radius = 0.1 }\nfractions = { water = 1.0 }\n");
    let mesh = parsed(&format!("[[fluid]]\nmesh = {{ path = {} }}\nfractions = {{ water = 1.0 }}\n", toml_path(&path)));
    let n_ball = sample_fluid(&ball, &sample_walls(&ball)).positions.len() as f64;
    let n_mesh = sample_fluid(&mesh, &sample_walls(&mesh)).positions.len() as f64;
    println!("sphere {n_ball} particles, icosphere {n_mesh}");
    assert!((n_mesh - n_ball).abs() / n_ball < 0.005, "sphere {n_ball}, icosphere {n_mesh}");

    // Its signed distance is the sphere's, less the polyhedron's sagitta.
    let shape = &mesh.fluids[0].shape;
    for p in [[0.0123f32, -0.0371, 0.2], [0.2, 0.0, 0.2], [0.0123, 0.05, 0.2]] {
        let want = sdf(&ball.fluids[0].shape, p);
        let got = sdf(shape, p);
        assert!((got - want).abs() < 2e-4, "{p:?}: {got} vs {want}");
    }

    // As a wall: a shell with signed distances in (-2d, 0], and fluid kept
    // out of its core.
    let walls = parsed(&format!(
        "[[fluid]]\nbox = {{ min = [-0.2, -0.25, 0.0], max = [0.2, 0.15, 0.4] }}\nfractions = {{ water = 1.0 }}\n\
         [[wall]]\nmesh = {{ path = {} }}\n",
        toml_path(&path)
    ));
    let w = sample_walls(&walls);
    assert!(!w.positions.is_empty());
    for &p in &w.positions {
        let s = sdf(&walls.walls[0].shape, p);
        assert!(s > -0.02 && s <= 0.0, "{p:?}: {s}");
    }
    let f = sample_fluid(&walls, &w);
    assert!(f.positions.iter().all(|&p| sdf(&ball.fluids[0].shape, p) > -0.005), "fluid inside the wall mesh");
}

#[test]
fn a_mesh_marks_the_fixed_part_of_a_solid() {
    let dir = TempDir::new("fixed");
    let path = cuboid([0.0, 0.0, 0.0], [0.05, 0.1, 0.1]).write(&dir, "clamp.stl");
    let s = parsed(&format!(
        "[[solid]]\nname = \"plate\"\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.3, 0.1, 0.1] }}\n\
         density = 500.0\nshear_modulus = 1e4\nlame_lambda = 1e4\nfixed = {{ mesh = {{ path = {} }} }}\n",
        toml_path(&path)
    ));
    let solids = sample_solids(&s, &sample_walls(&s));
    let fixed = solids.fixed.iter().filter(|&&f| f == 1).count();
    assert_eq!(fixed, 5 * 10 * 10);
    for (p, f) in solids.positions.iter().zip(&solids.fixed) {
        assert_eq!(*f == 1, p[0] < 0.05, "{p:?}");
    }
}

#[test]
fn a_mesh_path_is_relative_to_the_scene_file() {
    let dir = TempDir::new("relative");
    std::fs::create_dir_all(dir.path("meshes")).expect("mkdir");
    cuboid([0.0; 3], [0.1, 0.1, 0.1]).write(&dir, "meshes/block.obj");
    let scene_path = dir.path("scene.toml");
    std::fs::write(
        &scene_path,
        format!("{HEADER}[[fluid]]\nmesh = {{ path = \"meshes/block.obj\" }}\nfractions = {{ water = 1.0 }}\n"),
    )
    .expect("write scene");
    let s = Scene::from_file(&scene_path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sample_fluid(&s, &sample_walls(&s)).positions.len(), 1000);
}

/// The error of a fluid block filling `mesh_toml` (the inside of `mesh = { .. }`).
fn mesh_error(mesh_toml: &str) -> SceneError {
    match scene(&format!("[[fluid]]\nmesh = {{ {mesh_toml} }}\nfractions = {{ water = 1.0 }}\n")) {
        Ok(_) => panic!("accepted mesh = {{ {mesh_toml} }}"),
        Err(e) => e,
    }
}

#[test]
fn bad_meshes_are_errors_naming_the_file_and_the_reason() {
    let dir = TempDir::new("bad");
    let cube = cuboid([0.0; 3], [0.1, 0.1, 0.1]);
    let check = |path: &Path, extra: &str, key: &str, fragment: &str| {
        let e = mesh_error(&format!("path = {}{extra}", toml_path(path)));
        println!("{e}");
        assert_eq!(e.key, key, "{e}");
        assert!(e.reason.contains(&path.display().to_string()), "the file is not named: {e}");
        assert!(e.reason.contains(fragment), "reason lacks `{fragment}`: {e}");
    };
    let p = "fluid[0].mesh.path";

    check(&dir.path("missing.obj"), "", p, "cannot read: No such file");

    let open = Mesh { v: cube.v.clone(), t: cube.t[1..].to_vec() };
    check(&open.write(&dir, "open.obj"), "", p, "open: 3 edges belong to an odd number of triangles");

    let mut flipped = Mesh { v: cube.v.clone(), t: cube.t.clone() };
    flipped.t[4].swap(1, 2);
    check(&flipped.write(&dir, "flipped.stl"), "", p, "not consistently oriented");

    let empty = Mesh { v: cube.v.clone(), t: Vec::new() };
    check(&empty.write(&dir, "empty.obj"), "", p, "empty: the file has no triangles");

    let flat = Mesh { v: cube.v.clone(), t: vec![[0, 1, 3], [0, 3, 2], [0, 3, 1], [0, 2, 3]] };
    check(&flat.write(&dir, "flat.obj"), "", p, "degenerate: the surface encloses no volume");

    let junk = dir.path("junk.stl");
    std::fs::write(&junk, b"not an stl file").expect("write");
    check(&junk, "", p, "not a readable STL file");

    let ply = dir.path("cube.ply");
    std::fs::write(&ply, b"ply\n").expect("write");
    check(&ply, "", p, "unknown mesh format: expected a file name ending in .obj or .stl");

    // In mm instead of m: too big for the lattice; or moved far away.
    let path = cube.write(&dir, "cube.obj");
    check(&path, ", scale = 1000.0", "fluid[0].mesh", "lattice cells");
    let e = mesh_error(&format!("path = {}, scale = 2e5", toml_path(&path)));
    assert!(e.reason.contains("is more than 1e6 particle spacings from the origin; is the scale right?"), "{e}");
    let e = mesh_error(&format!("path = {}, translate = [0.0, 2e4, 0.0]", toml_path(&path)));
    assert_eq!(e.key, "fluid[0].mesh.translate[1]", "{e}");
}

/// Issue 36 item 8: a directory is said to be one; a bad OBJ line is named
/// by `file:line`, the reason and the line's text.
#[test]
fn a_directory_or_a_bad_obj_line_is_named() {
    let dir = TempDir::new("bad-lines");
    let p = "fluid[0].mesh.path";
    let folder = dir.path("folder.obj");
    std::fs::create_dir_all(&folder).expect("mkdir");
    let e = mesh_error(&format!("path = {}", toml_path(&folder)));
    assert_eq!(e.key, p, "{e}");
    assert!(e.reason.contains(&format!("mesh file {}: a directory, not a mesh file", folder.display())), "{e}");

    let cases = [
        (
            "letter.obj",
            "# a cube\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n",
            5,
            "face parse error (the line reads `f 1 2 x`)",
        ),
        ("vt.obj", "v 0 0 0\nvt 1 zz\nv 1 0 0", 2, "texcoord parse error (the line reads `vt 1 zz`)"),
        (
            "index.obj",
            "v 0 0 0\nv 1 0 0\nf 1 2 7\nv 0 1 0\n",
            3,
            "face vertex index 7 names no vertex (the file has 3, 2 before this line) (the line reads `f 1 2 7`)",
        ),
    ];
    for (name, text, line, reason) in cases {
        let path = dir.path(name);
        std::fs::write(&path, text).expect("write");
        let e = mesh_error(&format!("path = {}", toml_path(&path)));
        println!("{e}");
        assert_eq!(e.key, p, "{e}");
        let want = format!("mesh file {}:{line}: not a readable OBJ file: {reason}", path.display());
        assert!(e.reason.contains(&want), "{e}\nwanted: {want}");
    }
}
