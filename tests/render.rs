//! `porosph render`: pictures of the expected size; a known frame renders
//! its fluid and solid in their colours at the expected pixels and the
//! background elsewhere; walls hidden by default; an empty frame is a
//! background picture; `--movie` renders every frame; the camera options put
//! their target at the image centre and look from their eye; bad input is an
//! error naming the file, never a panic. The colour bar states the range
//! given with `--range` or the 1st-99th percentile (one range for a whole
//! movie); `--hide` and `--clip` leave out what they name; translucent
//! fluid shows the solid behind it; solids are outlined and a fluid of
//! their colour is not; bad options name the option and the reason.

mod common;

use common::TempDir;
use porosph::io::{write_frame, ArrayData, Frame, PointArray};
use porosph::render::{render, Camera, CameraSpec, ColorMode, RenderOptions};
use porosph::run::kind;
use std::path::Path;
use std::process::{Command, Output};

fn porosph(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_porosph")).args(args).output().expect("run porosph")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn array(name: &str, components: usize, data: ArrayData) -> PointArray {
    PointArray { name: name.into(), unit: String::new(), components, data }
}

/// A cube of 10^3 particles of spacing `d` centred at `c`.
fn blob(c: [f32; 3], d: f32) -> Vec<[f32; 3]> {
    let mut p = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            for k in 0..10 {
                p.push([0, 1, 2].map(|a| c[a] + d * ([i, j, k][a] as f32 - 4.5)));
            }
        }
    }
    p
}

const BLUE: [f32; 3] = [0.05, 0.2, 0.9];
const RED: [f32; 3] = [0.9, 0.05, 0.05];
const FLUID_AT: [f32; 3] = [-0.6, 0.0, 0.0];
const SOLID_AT: [f32; 3] = [0.6, 0.0, 0.0];
const WALL_AT: [f32; 3] = [0.0, 0.0, -0.3];

/// A blue fluid blob on the left (x < 0), a red solid blob on the right,
/// and a sheet of wall particles behind them between the two.
fn known_frame() -> Frame {
    let d = 0.03;
    let mut points = blob(FLUID_AT, d);
    let mut kinds = vec![kind::FLUID; points.len()];
    let mut color: Vec<f32> = points.iter().flat_map(|_| BLUE).collect();
    for p in blob(SOLID_AT, d) {
        points.push(p);
        kinds.push(kind::SOLID);
        color.extend(RED);
    }
    for i in 0..10 {
        for j in 0..10 {
            points.push([WALL_AT[0] + d * (i as f32 - 4.5), WALL_AT[1] + d * (j as f32 - 4.5), WALL_AT[2]]);
            kinds.push(kind::WALL);
            color.extend([0.6, 0.6, 0.6]);
        }
    }
    let n = points.len();
    let speed: Vec<f32> = points.iter().flat_map(|p| [p[0] + 1.0, 0.0, 0.0]).collect();
    Frame {
        time: 0.5,
        step: 10,
        points,
        arrays: vec![
            array("velocity", 3, ArrayData::F32(speed)),
            array("pressure", 1, ArrayData::F32((0..n).map(|i| i as f32).collect())),
            array("color", 3, ArrayData::F32(color)),
            array("kind", 1, ArrayData::U8(kinds)),
            array("id", 1, ArrayData::U32((0..n as u32).collect())),
        ],
    }
}

/// Without the time stamp and colour bar, so that the particles fill the
/// picture and its corners are background.
fn opts() -> RenderOptions {
    RenderOptions { width: 320, height: 200, annotate: false, ..RenderOptions::default() }
}

/// The pixel `p` projects to with the default camera of `frame`.
fn pixel_of(frame: &Frame, o: &RenderOptions, p: [f32; 3]) -> (u32, u32) {
    let (lo, hi) = porosph::render::bounds(frame, o.walls).unwrap().unwrap();
    let cam = Camera::framing(lo, hi, o.width, o.height, o.orthographic);
    let [x, y, _] = cam.project(p, o.width, o.height).unwrap();
    (x as u32, y as u32)
}

fn background(o: &RenderOptions) -> [u8; 3] {
    let img = render(&Frame::default(), &RenderOptions { width: 1, height: 1, ..o.clone() }).unwrap();
    img.pixel(0, 0)
}

fn blueish(c: [u8; 3]) -> bool {
    c[2] > 100 && c[2] as u32 > 2 * c[0] as u32 && c[2] > c[1]
}

fn redish(c: [u8; 3]) -> bool {
    c[0] > 100 && c[0] as u32 > 2 * c[2] as u32 && c[0] as u32 > 2 * c[1] as u32
}

#[test]
fn image_has_the_asked_size() {
    let f = known_frame();
    for (w, h) in [(320, 200), (64, 97), (1, 1)] {
        let img = render(&f, &RenderOptions { width: w, height: h, ..opts() }).unwrap();
        assert_eq!((img.width, img.height, img.rgb.len()), (w, h, 3 * (w * h) as usize));
    }
    // And the PNG says so.
    let png = render(&f, &opts()).unwrap().encode_png().unwrap();
    let dec = png::Decoder::new(std::io::Cursor::new(png)).read_info().unwrap();
    let info = dec.info();
    assert_eq!((info.width, info.height, info.color_type), (320, 200, png::ColorType::Rgb));
}

#[test]
fn fluid_and_solid_render_in_their_colours_where_expected() {
    let f = known_frame();
    for ortho in [false, true] {
        let o = RenderOptions { orthographic: ortho, ..opts() };
        let img = render(&f, &o).unwrap();
        let bg = background(&o);
        let (fx, fy) = pixel_of(&f, &o, FLUID_AT);
        let (sx, sy) = pixel_of(&f, &o, SOLID_AT);
        assert!(fx < o.width / 2 && sx > o.width / 2, "fluid at {fx}, solid at {sx}");
        assert!(blueish(img.pixel(fx, fy)), "ortho {ortho}: fluid pixel {:?}", img.pixel(fx, fy));
        assert!(redish(img.pixel(sx, sy)), "ortho {ortho}: solid pixel {:?}", img.pixel(sx, sy));
        // Background: the corners, the middle between the blobs (the wall
        // sheet is there, hidden), above and below.
        let (w, h) = (o.width, o.height);
        for (x, y) in [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1), (w / 2, h / 2), (fx, 2), (sx, h - 3)] {
            assert_eq!(img.pixel(x, y), bg, "ortho {ortho}: pixel ({x}, {y})");
        }
        // Most of the picture is background; the blobs cover a fair part.
        let n_bg = img.rgb.chunks(3).filter(|c| *c == bg).count();
        let total = (w * h) as usize;
        assert!(n_bg > total / 2 && n_bg < total - total / 50, "{n_bg} of {total} background pixels");
    }
}

#[test]
fn walls_hidden_by_default_and_faint_when_asked() {
    let f = known_frame();
    let o = opts();
    let bg = background(&o);
    // A wall particle's centre (the sheet's centre is a gap between four).
    let wall = [WALL_AT[0] + 0.015, WALL_AT[1] + 0.015, WALL_AT[2]];
    let (wx, wy) = pixel_of(&f, &o, wall);
    assert_eq!(render(&f, &o).unwrap().pixel(wx, wy), bg);
    // Shown, the walls are framed too: a different camera.
    let ow = RenderOptions { walls: true, ..o.clone() };
    let (wx, wy) = pixel_of(&f, &ow, wall);
    let shown = render(&f, &ow).unwrap().pixel(wx, wy);
    assert_ne!(shown, bg);
    // Faint: grey, close to the background.
    assert!(shown.iter().zip(bg).all(|(&a, b)| a.abs_diff(b) < 90), "{shown:?} vs {bg:?}");
}

#[test]
fn colormap_modes_differ_and_are_deterministic() {
    let f = known_frame();
    let base = render(&f, &opts()).unwrap();
    for mode in [ColorMode::Speed, ColorMode::Pressure] {
        let o = RenderOptions { color: mode, ..opts() };
        let a = common::with_threads(1, || render(&f, &o).unwrap());
        let b = common::with_threads(2, || render(&f, &o).unwrap());
        assert_eq!(a, b, "{mode:?}: same picture on 1 and 2 threads");
        assert_ne!(a, base);
    }
    let a = common::with_threads(1, || render(&f, &opts()).unwrap());
    let b = common::with_threads(2, || render(&f, &opts()).unwrap());
    assert_eq!(a, b);
}

#[test]
fn empty_frame_is_a_background_picture() {
    let o = opts();
    let bg = background(&o);
    let empty = Frame::default();
    let img = render(&empty, &o).unwrap();
    assert!(img.rgb.chunks(3).all(|c| c == bg));
    // Only walls (hidden): background too; and speed mode needs velocity.
    let mut f = known_frame();
    let k: Vec<u8> = vec![kind::WALL; f.points.len()];
    f.arrays.retain(|a| a.name != "kind");
    f.arrays.push(array("kind", 1, ArrayData::U8(k)));
    assert!(render(&f, &o).unwrap().rgb.chunks(3).all(|c| c == bg));
    let err =
        render(&Frame { points: vec![[0.0; 3]], ..Frame::default() }, &RenderOptions { color: ColorMode::Speed, ..o })
            .unwrap_err();
    assert!(err.0.contains("velocity"), "{err}");
}

#[test]
fn bad_arrays_and_sizes_are_errors() {
    let mut f = known_frame();
    f.arrays.retain(|a| a.name != "color");
    f.arrays.push(array("color", 3, ArrayData::F32(vec![0.5; 6])));
    let e = render(&f, &opts()).unwrap_err();
    assert!(e.0.contains("\"color\""), "{e}");
    let e = render(&known_frame(), &RenderOptions { width: 0, ..opts() }).unwrap_err();
    assert!(e.0.contains("image size"), "{e}");
    // Non-finite points are skipped, not a panic.
    let mut f = known_frame();
    f.points[0] = [f32::NAN, 0.0, 0.0];
    f.points[1] = [f32::INFINITY, 0.0, 0.0];
    render(&f, &opts()).unwrap();
}

#[test]
fn cli_renders_a_frame_and_a_movie() {
    let dir = TempDir::new("render-cli");
    let frames = dir.path("run/frames");
    std::fs::create_dir_all(&frames).unwrap();
    let f = known_frame();
    for i in 0..3 {
        write_frame(&frames.join(format!("frame_{i:05}.vtkhdf")), &f).unwrap();
    }
    let one = frames.join("frame_00001.vtkhdf");
    let png = dir.path("one.png");
    let out = porosph(&["render", s(&one), "-o", s(&png), "--width", "100", "--height", "80", "--color", "speed"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let dec = png::Decoder::new(std::fs::File::open(&png).unwrap()).read_info().unwrap();
    assert_eq!((dec.info().width, dec.info().height), (100, 80));

    let out = porosph(&["render", s(&dir.path("run")), "--movie", "--width", "64", "--height", "48"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for i in 0..3 {
        assert!(dir.path(&format!("run/render/frame_{i:05}.png")).is_file());
    }

    // Errors name the file and the reason; exit status 1, no panic.
    let missing = dir.path("nope.vtkhdf");
    let bad = dir.path("bad.vtkhdf");
    std::fs::write(&bad, b"not hdf5").unwrap();
    for (args, want) in [
        (vec!["render", s(&missing)], s(&missing).to_string()),
        (vec!["render", s(&bad)], s(&bad).to_string()),
        (vec!["render", s(&dir.path("run"))], "--movie".to_string()),
        (vec!["render", s(&one), "--movie"], "run directory".to_string()),
        (vec!["render", s(&dir.0), "--movie"], "frames".to_string()),
        (vec!["render", s(&one), "--width", "0"], "--width".to_string()),
        (vec!["render", s(&one), "-o", "/nonexistent-dir/x.png"], "/nonexistent-dir/x.png: cannot write".to_string()),
        (vec!["render", s(&one), "--color", "rainbow"], "rainbow".to_string()),
    ] {
        let out = porosph(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains(&want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

const GREEN: [f32; 3] = [0.05, 0.8, 0.05];
/// Where the marker of [`with_marker`] is: above the blobs, in front.
const MARK: [f32; 3] = [0.0, 0.5, 0.2];

fn greenish(c: [u8; 3]) -> bool {
    c[1] > 100 && c[1] as u32 > 2 * c[0] as u32 && c[1] as u32 > 2 * c[2] as u32
}

/// The known frame and one green fluid particle at [`MARK`].
fn with_marker() -> Frame {
    let mut f = known_frame();
    f.points.push(MARK);
    for a in &mut f.arrays {
        match (a.name.as_str(), &mut a.data) {
            ("velocity", ArrayData::F32(v)) => v.extend([0.0; 3]),
            ("pressure", ArrayData::F32(v)) => v.push(0.0),
            ("color", ArrayData::F32(v)) => v.extend(GREEN),
            ("kind", ArrayData::U8(v)) => v.push(kind::FLUID),
            ("id", ArrayData::U32(v)) => v.push(v.len() as u32),
            (name, _) => panic!("unexpected array {name}"),
        }
    }
    f
}

#[test]
fn camera_target_lands_at_the_image_centre() {
    let f = with_marker();
    let (lo, hi) = porosph::render::bounds(&f, false).unwrap().unwrap();
    for (eye, fov, ortho) in [
        (Some([0.3, 0.9, 1.5]), None, false),
        (None, None, false),                  // the default direction and distance
        (Some([0.0, 2.0, 0.2]), None, false), // straight down
        (Some([-1.0, 0.5, -1.0]), Some(20.0), false),
        (Some([1.0, 1.0, 1.0]), None, true),
    ] {
        let view = CameraSpec { eye, target: Some(MARK), fov_deg: fov };
        let o = RenderOptions { view, orthographic: ortho, radius: Some(0.02), ..opts() };
        let cam = Camera::aimed(lo, hi, &view, o.width, o.height, ortho);
        let [x, y, _] = cam.project(MARK, o.width, o.height).unwrap();
        assert!((x - 160.0).abs() < 1e-3 && (y - 100.0).abs() < 1e-3, "{view:?}: marker at ({x}, {y})");
        if let Some(e) = eye {
            assert_eq!(cam.eye, e);
        }
        let img = render(&f, &o).unwrap();
        assert!(greenish(img.pixel(160, 100)), "{view:?}: centre pixel {:?}", img.pixel(160, 100));
    }
}

#[test]
fn camera_eye_sets_the_side_seen_from() {
    let f = known_frame();
    let (lo, hi) = porosph::render::bounds(&f, false).unwrap().unwrap();
    // From the front (+z) the fluid (x < 0) is on the left; from behind, on
    // the right; from above, on the left, also with the eye a little off
    // the vertical to either side (-z is up: no turn for small offsets).
    for (eye, fluid_left) in [
        ([0.0, 0.0, 3.0], true),
        ([0.0, 0.0, -3.0], false),
        ([0.0, 3.0, 0.0], true),
        ([0.0, 3.0, 0.05], true),
        ([0.0, 3.0, -0.05], true),
    ] {
        let view = CameraSpec { eye: Some(eye), target: Some([0.0; 3]), fov_deg: None };
        let o = RenderOptions { view, ..opts() };
        let cam = Camera::aimed(lo, hi, &view, o.width, o.height, false);
        let [x, y, _] = cam.project(FLUID_AT, o.width, o.height).unwrap();
        assert_eq!(x < 160.0, fluid_left, "eye {eye:?}: fluid at x = {x}");
        let img = render(&f, &o).unwrap();
        assert!(blueish(img.pixel(x as u32, y as u32)), "eye {eye:?}: {:?}", img.pixel(x as u32, y as u32));
    }
    // A bad spec is an error, not a picture.
    for (view, want) in [
        (CameraSpec { eye: Some(MARK), target: Some(MARK), fov_deg: None }, "same point"),
        (CameraSpec { fov_deg: Some(0.0), ..CameraSpec::default() }, "field of view"),
        (CameraSpec { target: Some([f32::NAN, 0.0, 0.0]), ..CameraSpec::default() }, "finite"),
    ] {
        let e = render(&f, &RenderOptions { view, ..opts() }).unwrap_err();
        assert!(e.0.contains(want), "{view:?}: {e}");
    }
}

#[test]
fn cli_camera_options() {
    let dir = TempDir::new("render-camera");
    let frame = dir.path("f.vtkhdf");
    write_frame(&frame, &with_marker()).unwrap();
    let png = dir.path("f.png");
    // A negative coordinate as the next argument, and as --eye=.
    for eye in [vec!["--eye", "-0.3,0.9,1.5"], vec!["--eye=-0.3,0.9,1.5"]] {
        let mut args = vec!["render", s(&frame), "-o", s(&png), "--width", "101", "--height", "81"];
        args.extend(eye);
        args.extend(["--target", "0,0.5,0.2", "--fov", "25"]);
        let out = porosph(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let mut dec = png::Decoder::new(std::fs::File::open(&png).unwrap()).read_info().unwrap();
        let mut buf = vec![0; dec.output_buffer_size()];
        dec.next_frame(&mut buf).unwrap();
        let at = 3 * (40 * 101 + 50);
        let centre = [buf[at], buf[at + 1], buf[at + 2]];
        assert!(greenish(centre), "centre pixel {centre:?}");
    }
    let help = String::from_utf8_lossy(&porosph(&["render", "--help"]).stdout).to_string();
    for want in ["--eye <X,Y,Z>", "--target <X,Y,Z>", "--fov <DEGREES>", "phase (the phase mixture)"] {
        assert!(help.contains(want), "{want} not in --help:\n{help}");
    }
    for (args, want) in [
        (vec!["--eye", "1,2"], "X,Y,Z"),
        (vec!["--eye", "1,2,x"], "X,Y,Z"),
        (vec!["--target", "1,2,inf"], "finite"),
        (vec!["--fov", "0"], "1 to 179 degrees"),
        (vec!["--fov", "30", "--ortho"], "cannot be used with"),
        (vec!["--eye", "0,0.5,0.2", "--target", "0,0.5,0.2"], "same point"),
    ] {
        let mut all = vec!["render", s(&frame), "-o", s(&png)];
        all.extend(&args);
        let out = porosph(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// Blob centres of [`porous_frame`]: fluid outside the solids (alpha),
/// absorbed fluid (beta), a dry and a wet porous solid, left to right.
const OUTER_AT: [f32; 3] = [-0.9, 0.0, 0.0];
const INNER_AT: [f32; 3] = [-0.3, 0.0, 0.0];
const DRY_AT: [f32; 3] = [0.3, 0.0, 0.0];
const WET_AT: [f32; 3] = [0.9, 0.0, 0.0];

/// A frame as a run with porous solids writes it: two phases (blue, red),
/// `alpha` and `beta` per fluid point, `saturation` per solid point, the
/// frame's `color` (inner fluid at 0.45 of its phase colour, as
/// `Simulation::frame` draws it), and a wall sheet behind.
fn porous_frame() -> Frame {
    let d = 0.03;
    let (mut points, mut kinds, mut color) = (Vec::new(), Vec::new(), Vec::new());
    let (mut alpha, mut beta, mut sat) = (Vec::new(), Vec::new(), Vec::new());
    // (centre, kind, alpha, beta, saturation, colour)
    let shade = porosph::run::INNER_SHADE;
    let blobs = [
        (OUTER_AT, kind::FLUID, [1.0, 0.0], [0.0, 0.0], 0.0, BLUE),
        (INNER_AT, kind::FLUID, [0.0, 0.0], [1.0, 0.0], 0.0, BLUE.map(|c| shade * c)),
        (DRY_AT, kind::SOLID, [0.0; 2], [0.0; 2], 0.0, [0.8, 0.62, 0.38]),
        (WET_AT, kind::SOLID, [0.0; 2], [0.0; 2], 0.5, [0.85, 0.33, 0.05]),
    ];
    for (c, k, a, b, s, col) in blobs {
        for p in blob(c, d) {
            points.push(p);
            kinds.push(k);
            alpha.extend(a);
            beta.extend(b);
            sat.push(s);
            color.extend(col);
        }
    }
    for i in 0..10 {
        for j in 0..10 {
            points.push([WALL_AT[0] + d * (i as f32 - 4.5), WALL_AT[1] + d * (j as f32 - 4.5), WALL_AT[2]]);
            kinds.push(kind::WALL);
            alpha.extend([0.0; 2]);
            beta.extend([0.0; 2]);
            sat.push(0.0);
            color.extend([0.6, 0.6, 0.6]);
        }
    }
    let n = points.len();
    Frame {
        time: 0.5,
        step: 10,
        points,
        arrays: vec![
            array("velocity", 3, ArrayData::F32(vec![0.0; 3 * n])),
            array("pressure", 1, ArrayData::F32(vec![0.0; n])),
            array("saturation", 1, ArrayData::F32(sat)),
            array("alpha", 2, ArrayData::F32(alpha)),
            array("beta", 2, ArrayData::F32(beta)),
            array("color", 3, ArrayData::F32(color)),
            array("kind", 1, ArrayData::U8(kinds)),
            array("id", 1, ArrayData::U32((0..n as u32).collect())),
        ],
    }
}

/// The mean sRGB colour of the 11 x 11 pixels around where `p` lands (a
/// few particles: the shading of single pixels varies over each sphere).
fn mean_around(img: &porosph::render::Image, frame: &Frame, o: &RenderOptions, p: [f32; 3]) -> [f32; 3] {
    let (x, y) = pixel_of(frame, o, p);
    let mut sum = [0.0f32; 3];
    for py in y - 5..=y + 5 {
        for px in x - 5..=x + 5 {
            let c = img.pixel(px, py);
            (0..3).for_each(|i| sum[i] += f32::from(c[i]) / 121.0);
        }
    }
    sum
}

fn brightness(c: [f32; 3]) -> f32 {
    c.iter().sum()
}

#[test]
fn saturation_mode_colours_solids_dry_to_wet_and_absorbed_fluid_darker() {
    let f = porous_frame();
    for ortho in [true, false] {
        let o = RenderOptions { color: ColorMode::Saturation, orthographic: ortho, ..opts() };
        let img = render(&f, &o).unwrap();
        let outer = mean_around(&img, &f, &o, OUTER_AT);
        let inner = mean_around(&img, &f, &o, INNER_AT);
        let dry = mean_around(&img, &f, &o, DRY_AT);
        let wet = mean_around(&img, &f, &o, WET_AT);
        let ctx = format!("ortho {ortho}: outer {outer:?} inner {inner:?} dry {dry:?} wet {wet:?}");
        // Fluid: its phase (blue) outside the solids and absorbed, the
        // absorbed fluid much darker.
        for c in [outer, inner] {
            assert!(c[2] > 2.0 * c[0] && c[2] > c[1], "{ctx}");
        }
        assert!(outer[2] > 100.0, "{ctx}");
        assert!(brightness(inner) < 0.65 * brightness(outer), "{ctx}");
        // Solids: dry pale sand (all channels high, red > green > blue),
        // wet (the top of the default range, 0 to the largest saturation)
        // dark brown.
        assert!(dry[0] > dry[1] && dry[1] > dry[2] && dry[2] > 0.6 * dry[0] && dry[0] > 120.0, "{ctx}");
        assert!(wet[0] > 2.0 * wet[1] && wet[0] > 3.0 * wet[2], "{ctx}");
        assert!(brightness(wet) < 0.6 * brightness(dry), "{ctx}");
        // Not the phase mode's picture (the frame's `color`).
        assert_ne!(img, render(&f, &RenderOptions { color: ColorMode::Phase, ..o.clone() }).unwrap());
    }
    // A range of 0 to 1: saturation 0.5 is half way, orange.
    let o = RenderOptions { color: ColorMode::Saturation, orthographic: true, range: Some([0.0, 1.0]), ..opts() };
    let img = render(&f, &o).unwrap();
    let half = mean_around(&img, &f, &o, WET_AT);
    assert!(half[0] > half[1] && half[1] > 1.5 * half[2] && half[1] > 0.4 * half[0], "half wet {half:?}");
    assert_eq!(porosph::render::value_range(&f, ColorMode::Saturation).unwrap(), Some([0.0, 0.5]));
    // Walls, when shown, are faint.
    let ow = RenderOptions { walls: true, ..o.clone() };
    let wall = [WALL_AT[0] + 0.015, WALL_AT[1] + 0.015, WALL_AT[2]];
    let (wx, wy) = pixel_of(&f, &ow, wall);
    let shown = render(&f, &ow).unwrap().pixel(wx, wy);
    let bg = background(&RenderOptions { color: ColorMode::Phase, ..ow.clone() });
    assert_ne!(shown, bg);
    assert!(shown.iter().zip(bg).all(|(&a, b)| a.abs_diff(b) < 90), "{shown:?} vs {bg:?}");
    // Deterministic on any number of threads.
    let a = common::with_threads(1, || render(&f, &o).unwrap());
    let b = common::with_threads(2, || render(&f, &o).unwrap());
    assert_eq!(a, b);
    // A frame without saturations (no porous solids written) is an error.
    let e = render(&known_frame(), &RenderOptions { color: ColorMode::Saturation, ..opts() }).unwrap_err();
    assert!(e.0.contains("saturation"), "{e}");
}

/// A PNG file read back: its size, RGB bytes and `tEXt` chunks.
struct Png {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
    text: Vec<(String, String)>,
}

impl Png {
    fn read(path: &Path) -> Png {
        let mut dec = png::Decoder::new(std::fs::File::open(path).unwrap()).read_info().unwrap();
        let mut rgb = vec![0; dec.output_buffer_size()];
        dec.next_frame(&mut rgb).unwrap();
        let info = dec.info();
        let text = info.uncompressed_latin1_text.iter().map(|t| (t.keyword.clone(), t.text.clone())).collect();
        Png { width: info.width, height: info.height, rgb, text }
    }

    fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y * self.width + x) as usize;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    fn pixels(&self) -> impl Iterator<Item = [u8; 3]> + '_ {
        self.rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]])
    }

    fn text(&self, key: &str) -> &str {
        self.text
            .iter()
            .find(|t| t.0 == key)
            .map(|t| t.1.as_str())
            .unwrap_or_else(|| panic!("no {key} in {:?}", self.text))
    }

    /// The `porosph:range` the picture states.
    fn range(&self) -> [f32; 2] {
        let v: Vec<f32> = self.text("porosph:range").split(',').map(|x| x.parse().unwrap()).collect();
        [v[0], v[1]]
    }
}

fn srgb8(c: [f32; 3]) -> [u8; 3] {
    c.map(|c| {
        let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
        (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    })
}

/// Runs `porosph render ARGS` and checks that it succeeded; its stderr.
fn render_ok(args: &[&str]) -> String {
    let out = porosph(args);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{args:?}: {err}");
    err
}

#[test]
fn colour_bar_range_is_the_range_given() {
    let dir = TempDir::new("render-range");
    let frame = dir.path("f.vtkhdf");
    write_frame(&frame, &known_frame()).unwrap();
    let png = dir.path("f.png");
    let err = render_ok(&[
        "render",
        s(&frame),
        "-o",
        s(&png),
        "--color",
        "pressure",
        "--range",
        "100,1500",
        "--width",
        "640",
        "--height",
        "360",
    ]);
    assert!(err.contains("colour range: pressure 100 to 1500 Pa (--range)"), "{err}");
    let img = Png::read(&png);
    assert_eq!(img.range(), [100.0, 1500.0]);
    assert_eq!(
        (img.text("porosph:field"), img.text("porosph:unit"), img.text("porosph:time")),
        ("pressure", "Pa", "0.5")
    );
    // The bar in the panel at the right: a column running from the
    // colormap's top (at the range's top) down to its bottom.
    let x0 = img.width - porosph::render::panel_width(img.width, img.height);
    let (top, bottom) = (srgb8(porosph::render::colormap(1.0)), srgb8(porosph::render::colormap(0.0)));
    let bar_x = (x0..img.width)
        .find(|&x| {
            (0..img.height).any(|y| img.pixel(x, y) == top) && (0..img.height).any(|y| img.pixel(x, y) == bottom)
        })
        .expect("a colour bar column");
    let ys = |c| (0..img.height).filter(|&y| img.pixel(bar_x, y) == c).collect::<Vec<_>>();
    assert!(ys(top)[0] < ys(bottom)[0], "the top of the bar is the top of the range");
    // The library states the same scale.
    let o = RenderOptions { color: ColorMode::Pressure, range: Some([100.0, 1500.0]), ..opts() };
    let scale = porosph::render::color_scale(&known_frame(), &o).unwrap().unwrap();
    assert_eq!((scale.range, scale.unit.as_str(), scale.given), ([100.0, 1500.0], "Pa", true));
}

#[test]
fn default_range_is_the_percentiles_and_ignores_an_outlier() {
    let dir = TempDir::new("render-percentile");
    // Pressures 0..n-1 (n = 2100 points), and one particle at 1e7 Pa.
    let mut f = known_frame();
    for a in &mut f.arrays {
        if let ("pressure", ArrayData::F32(p)) = (a.name.as_str(), &mut a.data) {
            p[5] = 1e7;
        }
    }
    let frame = dir.path("f.vtkhdf");
    write_frame(&frame, &f).unwrap();
    let png = dir.path("f.png");
    render_ok(&["render", s(&frame), "-o", s(&png), "--color", "pressure"]);
    // The drawn points are the 2000 fluid and solid ones (walls hidden):
    // pressures 0..1999 but 5, and 1e7; nearest ranks 20 and 1979 of 2000.
    let [lo, hi] = Png::read(&png).range();
    assert_eq!((lo, hi), (21.0, 1980.0), "1st and 99th percentile");
    // A movie shares one range: the percentiles over all its frames.
    let run = dir.path("run");
    std::fs::create_dir_all(run.join("frames")).unwrap();
    let mut g = f.clone();
    for a in &mut g.arrays {
        if let ("pressure", ArrayData::F32(p)) = (a.name.as_str(), &mut a.data) {
            p.iter_mut().for_each(|v| *v += 10_000.0);
        }
    }
    write_frame(&run.join("frames/frame_00000.vtkhdf"), &f).unwrap();
    write_frame(&run.join("frames/frame_00001.vtkhdf"), &g).unwrap();
    let err = render_ok(&["render", s(&run), "--movie", "--color", "pressure", "--width", "320", "--height", "180"]);
    let mut all: Vec<f32> = Vec::new();
    for fr in [&f, &g] {
        let o = RenderOptions { color: ColorMode::Pressure, ..opts() };
        all.extend(porosph::render::field_values(fr, &o).unwrap().unwrap());
    }
    let want = porosph::render::robust_range(ColorMode::Pressure, &mut all).unwrap();
    for i in 0..2 {
        assert_eq!(Png::read(&run.join(format!("render/frame_{i:05}.png"))).range(), want, "frame {i}");
    }
    assert!(err.contains("percentile over all frames"), "{err}");
    assert!(want[0] < 1000.0 && want[1] > 10_000.0 && want[1] < 12_000.0, "{want:?}");
}

/// Renders the known frame through the binary with `extra` options, the
/// time stamp and colour bar left out; the picture read back.
fn cli_render(dir: &TempDir, name: &str, extra: &[&str]) -> Png {
    let frame = dir.path("known.vtkhdf");
    if !frame.exists() {
        write_frame(&frame, &known_frame()).unwrap();
    }
    let png = dir.path(&format!("{name}.png"));
    let mut args = vec!["render", s(&frame), "-o", s(&png), "--width", "320", "--height", "200", "--no-annotations"];
    args.extend(extra);
    render_ok(&args);
    Png::read(&png)
}

#[test]
fn hide_leaves_out_the_kinds_named() {
    let dir = TempDir::new("render-hide");
    let all = cli_render(&dir, "all", &[]);
    assert!(all.pixels().any(blueish) && all.pixels().any(redish));
    let no_fluid = cli_render(&dir, "no_fluid", &["--hide", "fluid"]);
    assert!(!no_fluid.pixels().any(blueish), "fluid pixels with --hide fluid");
    assert!(no_fluid.pixels().any(redish));
    let no_solids = cli_render(&dir, "no_solids", &["--hide", "solids"]);
    assert!(no_solids.pixels().any(blueish) && !no_solids.pixels().any(redish));
    // Repeated or a list: nothing left, a background picture.
    let bg = background(&opts());
    for args in [vec!["--hide", "fluid", "--hide", "solids"], vec!["--hide", "fluid,solids,walls", "--walls"]] {
        let none = cli_render(&dir, "none", &args);
        assert!(none.pixels().all(|c| c == bg), "{args:?}");
    }
}

#[test]
fn clip_leaves_out_the_particles_past_the_plane() {
    let dir = TempDir::new("render-clip");
    let f = known_frame();
    let (fx, fy) = pixel_of(&f, &opts(), FLUID_AT);
    // Fluid at x = -0.6, solid at +0.6: x<0 keeps the fluid only, where it
    // was (the camera does not move).
    let left = cli_render(&dir, "left", &["--clip", "x<0"]);
    assert!(!left.pixels().any(redish), "solid pixels past x<0");
    assert!(blueish(left.pixel(fx, fy)), "{:?}", left.pixel(fx, fy));
    let right = cli_render(&dir, "right", &["--clip", "x>0"]);
    assert!(!right.pixels().any(blueish) && right.pixels().any(redish));
    // Half of each blob (x within 0.135 of its centre): fewer pixels.
    let blue = |p: &Png| p.pixels().filter(|&c| blueish(c)).count();
    let half = cli_render(&dir, "half", &["--clip", "x<-0.6", "--clip", "x>-1"]);
    let full = cli_render(&dir, "full", &[]);
    let (h, w) = (blue(&half), blue(&full));
    assert!(h > w / 4 && h < 3 * w / 4, "{h} of {w} fluid pixels with half the fluid");
    assert!(!half.pixels().any(redish));
}

#[test]
fn translucent_fluid_shows_the_solid_behind_it() {
    // The fluid blob moved in front of the solid blob, seen straight along
    // -z through a column of particles of both.
    let mut f = known_frame();
    for p in &mut f.points[..1000] {
        *p = [p[0] + 1.2, p[1], p[2] + 0.6];
    }
    let at = [SOLID_AT[0] + 0.015, SOLID_AT[1] + 0.015, SOLID_AT[2]];
    let view = CameraSpec { eye: Some([at[0], at[1], 3.0]), target: Some(at), fov_deg: None };
    let o = RenderOptions { view, ..opts() };
    let (cx, cy) = (o.width / 2, o.height / 2);
    let opaque = render(&f, &o).unwrap().pixel(cx, cy);
    let veiled = render(&f, &RenderOptions { fluid_opacity: 0.3, ..o.clone() }).unwrap().pixel(cx, cy);
    assert!(blueish(opaque), "opaque fluid in front: {opaque:?}");
    assert!(veiled[0] > opaque[0] + 60 && veiled[0] > veiled[2], "solid red through 30 % fluid: {veiled:?}");
    // Invisible fluid: as with the fluid hidden (the camera is fixed).
    let hide = porosph::render::Hide { fluid: true, ..Default::default() };
    let gone = render(&f, &RenderOptions { fluid_opacity: 0.0, ..o.clone() }).unwrap();
    assert_eq!(gone, render(&f, &RenderOptions { hide, ..o.clone() }).unwrap());
    let e = render(&f, &RenderOptions { fluid_opacity: 1.5, ..opts() }).unwrap_err();
    assert!(e.0.contains("fluid opacity"), "{e}");
}

#[test]
fn solids_are_outlined_and_a_fluid_of_their_colour_is_not() {
    // Both blobs in the dry-sponge colour, as a 50/50 red/green mixture
    // nearly is: the solid has a dark outline, the fluid none.
    let mut f = known_frame();
    for a in &mut f.arrays {
        if let ("color", ArrayData::F32(c)) = (a.name.as_str(), &mut a.data) {
            c.chunks_exact_mut(3).for_each(|c| c.copy_from_slice(&[0.8, 0.62, 0.38]));
        }
    }
    let o = opts();
    let img = render(&f, &o).unwrap();
    let dark = |p: [f32; 3]| {
        let (x, y) = pixel_of(&f, &o, p);
        let mut n = 0;
        for py in y.saturating_sub(40)..(y + 40).min(o.height) {
            for px in x.saturating_sub(40)..(x + 40).min(o.width) {
                n += usize::from(img.pixel(px, py).iter().all(|&c| c < 60));
            }
        }
        n
    };
    let (solid, fluid) = (dark(SOLID_AT), dark(FLUID_AT));
    assert!(solid > 100 && fluid == 0, "dark pixels: solid {solid}, fluid {fluid}");
}

#[test]
fn time_stamp_and_colour_bar_are_drawn() {
    let f = known_frame();
    let o = RenderOptions { width: 640, height: 360, color: ColorMode::Speed, ..opts() };
    let plain = render(&f, &o).unwrap();
    let annotated = render(&f, &RenderOptions { annotate: true, ..o.clone() }).unwrap();
    // The time stamp at the top left: dark text where there was none.
    let ink = (0..30)
        .flat_map(|y| (0..120).map(move |x| (x, y)))
        .filter(|&(x, y)| annotated.pixel(x, y) != plain.pixel(x, y) && annotated.pixel(x, y).iter().all(|&c| c < 128))
        .count();
    assert!(ink > 20, "{ink} pixels of text");
    // The colour bar's panel at the right: the colormap's ends.
    let x0 = 640 - porosph::render::panel_width(640, 360);
    let panel: Vec<[u8; 3]> =
        (0..360).flat_map(|y| (x0..640).map(move |x| (x, y))).map(|(x, y)| annotated.pixel(x, y)).collect();
    for t in [0.0, 1.0] {
        assert!(panel.contains(&srgb8(porosph::render::colormap(t))), "colormap({t}) in the bar");
    }
    // The phase colours have no bar; thumbnails have no annotations.
    let phase = render(&f, &RenderOptions { annotate: true, color: ColorMode::Phase, ..o.clone() }).unwrap();
    assert!(!phase.rgb.chunks(3).any(|c| c == srgb8(porosph::render::colormap(1.0))));
    let small = RenderOptions { width: 200, height: 100, ..o.clone() };
    assert_eq!(render(&f, &RenderOptions { annotate: true, ..small.clone() }).unwrap(), render(&f, &small).unwrap());
}

#[test]
fn bad_render_options_name_the_option_and_the_reason() {
    let dir = TempDir::new("render-bad-options");
    let frame = dir.path("f.vtkhdf");
    write_frame(&frame, &known_frame()).unwrap();
    let png = dir.path("x.png");
    for (args, want) in [
        (vec!["--color", "pressure", "--range", "5,1"], ["--range", "MIN must be less than MAX"]),
        (vec!["--color", "pressure", "--range", "5"], ["--range", "two numbers MIN,MAX"]),
        (vec!["--color", "pressure", "--range", "0,inf"], ["--range", "finite"]),
        (vec!["--range", "0,1"], ["--range", "--color phase has none"]),
        (vec!["--clip", "q<1"], ["--clip", "the axis must be x, y or z"]),
        (vec!["--clip", "x=1"], ["--clip", "no < or >"]),
        (vec!["--clip", "x<abc"], ["--clip", "not a finite number"]),
        (vec!["--hide", "water"], ["--hide", "not a particle kind"]),
        (vec!["--fluid-opacity", "2"], ["--fluid-opacity", "0 (invisible) to 1 (opaque)"]),
    ] {
        let mut all = vec!["render", s(&frame), "-o", s(&png)];
        all.extend(&args);
        let out = porosph(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        for w in want {
            assert!(err.contains(w), "{args:?}: {w:?} not in {err}");
        }
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!png.exists());
}
