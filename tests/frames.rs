//! Frame files (VTKHDF) and the series index: what is written reads back
//! exactly, writes are atomic, and bad files give errors, not panics. A
//! run's frames (issue 36, item 5) name their phases, keep the static walls
//! once in `walls.vtkhdf` and still read back (and render) whole, can be
//! compressed, and give every particle a meaningful density.

mod common;

use porosph::io::{
    inspect_frame, read_frame, write_frame, write_frame_as, ArrayData, Frame, FrameLayout, PointArray, SeriesWriter,
    SharedRows,
};
use porosph::pipeline::Simulation;
use porosph::run::kind;
use std::fs;
use std::path::PathBuf;

/// A fresh, empty directory for one test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("porosph-frames-{}-{test}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// A frame of `n` points with f32 (1 and 3 components), u32 and u8 arrays;
/// values are deterministic and include awkward floats.
fn sample_frame(n: usize) -> Frame {
    let points = (0..n).map(|i| [i as f32 * 1e-3, -(i as f32) * 0.25, 1.0 / (i as f32 + 3.0)]).collect();
    let velocity = (0..n * 3).map(|k| (k as f32).sin() * 1e-7).collect();
    let density = (0..n).map(|i| 1000.0 + i as f32 * 0.1 + f32::EPSILON).collect();
    let id = (0..n).map(|i| (i as u32).wrapping_mul(2_654_435_761)).collect();
    let kind = (0..n).map(|i| (i % 3) as u8).collect();
    Frame {
        time: 0.1 + 0.2,
        step: 12_345,
        points,
        arrays: vec![
            PointArray { name: "velocity".into(), unit: "m/s".into(), components: 3, data: ArrayData::F32(velocity) },
            PointArray { name: "density".into(), unit: "kg/m³".into(), components: 1, data: ArrayData::F32(density) },
            PointArray { name: "id".into(), unit: "".into(), components: 1, data: ArrayData::U32(id) },
            PointArray { name: "kind".into(), unit: "".into(), components: 1, data: ArrayData::U8(kind) },
        ],
    }
}

fn assert_round_trip(n: usize) {
    let dir = TempDir::new(&format!("round-trip-{n}"));
    let path = dir.path("frame_00001.vtkhdf");
    let frame = sample_frame(n);
    write_frame(&path, &frame).expect("write");
    let back = read_frame(&path).expect("read");
    // PartialEq on f32 would also pass for -0.0 vs 0.0; compare bits.
    assert_eq!(back.time.to_bits(), frame.time.to_bits());
    assert_eq!(back.step, frame.step);
    let bits = |p: &[[f32; 3]]| p.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back.points), bits(&frame.points));
    assert_eq!(back, frame, "arrays, names, units, order and components survive");
}

#[test]
fn round_trip_of_1000_points_keeps_every_array() {
    assert_round_trip(1000);
}

#[test]
fn round_trip_of_one_point() {
    assert_round_trip(1);
}

#[test]
fn round_trip_of_an_empty_frame() {
    assert_round_trip(0);
    let dir = TempDir::new("empty-no-arrays");
    let path = dir.path("empty.vtkhdf");
    let frame = Frame::default();
    write_frame(&path, &frame).expect("write");
    assert_eq!(read_frame(&path).expect("read"), frame);
}

#[test]
fn write_leaves_no_temporary_file_and_replaces_an_old_frame() {
    let dir = TempDir::new("no-temp");
    let path = dir.path("frame_00000.vtkhdf");
    write_frame(&path, &sample_frame(10)).expect("first write");
    write_frame(&path, &sample_frame(20)).expect("second write over the first");
    let names: Vec<String> = fs::read_dir(&dir.0)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["frame_00000.vtkhdf".to_string()]);
    assert_eq!(read_frame(&path).expect("read").points.len(), 20);
}

#[test]
fn write_into_a_missing_directory_names_the_path() {
    let dir = TempDir::new("missing-dir");
    let path = dir.path("no/such/dir/frame_00000.vtkhdf");
    let err = write_frame(&path, &sample_frame(5)).expect_err("must fail");
    assert_eq!(err.path, path);
    let text = err.to_string();
    assert!(text.contains("no/such/dir/frame_00000.vtkhdf"), "{text}");
    assert!(!dir.path("no").exists());
}

#[test]
fn write_rejects_an_array_of_the_wrong_length() {
    let dir = TempDir::new("wrong-length");
    let path = dir.path("f.vtkhdf");
    let mut frame = sample_frame(10);
    frame.arrays[0].components = 2;
    let err = write_frame(&path, &frame).expect_err("must fail");
    assert!(err.reason.contains("velocity"), "{err}");
    assert!(!path.exists());
}

#[test]
fn read_of_a_truncated_file_is_an_error() {
    let dir = TempDir::new("truncated");
    let path = dir.path("frame.vtkhdf");
    write_frame(&path, &sample_frame(1000)).expect("write");
    let bytes = fs::read(&path).expect("read bytes");
    for keep in [0, 8, 100, bytes.len() / 2, bytes.len() - 1] {
        let cut = dir.path(&format!("cut_{keep}.vtkhdf"));
        fs::write(&cut, &bytes[..keep]).expect("write cut");
        let err = read_frame(&cut).expect_err("truncated file must not read");
        assert_eq!(err.path, cut);
    }
}

#[test]
fn read_of_a_text_file_or_a_missing_file_is_an_error() {
    let dir = TempDir::new("text");
    let text = dir.path("notes.vtkhdf");
    fs::write(&text, "this is not HDF5\n").expect("write text");
    let err = read_frame(&text).expect_err("text file");
    assert!(err.reason.contains("HDF5"), "{err}");

    let missing = dir.path("missing.vtkhdf");
    let err = read_frame(&missing).expect_err("missing file");
    assert_eq!(err.path, missing);
    assert!(inspect_frame(&missing).is_err());
}

#[test]
fn read_of_an_hdf5_file_without_vtkhdf_group_is_an_error() {
    let dir = TempDir::new("plain-hdf5");
    let path = dir.path("plain.h5");
    let file = hdf5::File::create(&path).expect("create");
    file.create_group("Other").expect("group");
    file.close().expect("close");
    let err = read_frame(&path).expect_err("no /VTKHDF");
    assert!(err.reason.contains("VTKHDF"), "{err}");
}

#[test]
fn inspect_summarizes_time_step_arrays_and_kinds() {
    let dir = TempDir::new("inspect");
    let path = dir.path("frame.vtkhdf");
    write_frame(&path, &sample_frame(10)).expect("write");
    let text = inspect_frame(&path).expect("inspect");
    for needle in ["points: 10", "step:   12345", "velocity", "m/s", "density", "kg/m³", "fluid 4, solid 3, wall 3"] {
        assert!(text.contains(needle), "missing {needle:?} in\n{text}");
    }
}

#[test]
fn series_file_after_three_adds_lists_them_in_order() {
    let dir = TempDir::new("series");
    let path = dir.path("frames.vtkhdf.series");
    let mut series = SeriesWriter::new(&path);
    assert!(!path.exists(), "nothing written before the first add");
    series.add("frame_00000.vtkhdf", 0.0).expect("add 0");
    series.add("frame_00001.vtkhdf", 0.1).expect("add 1");
    series.add("frame_\"2\".vtkhdf", 0.30000000000000004).expect("add 2");
    let text = fs::read_to_string(&path).expect("read series");
    let expected = "{\n  \"file-series-version\" : \"1.0\",\n  \"files\" : [\n    \
        { \"name\" : \"frame_00000.vtkhdf\", \"time\" : 0.0 },\n    \
        { \"name\" : \"frame_00001.vtkhdf\", \"time\" : 0.1 },\n    \
        { \"name\" : \"frame_\\\"2\\\".vtkhdf\", \"time\" : 0.30000000000000004 }\n  ]\n}\n";
    assert_eq!(text, expected);
    let names: Vec<String> = fs::read_dir(&dir.0)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["frames.vtkhdf.series".to_string()], "no temporary file left");

    let mut resumed = SeriesWriter::open_existing(&path).expect("reopen");
    assert_eq!(resumed.entries(), series.entries());
    resumed.add("frame_00003.vtkhdf", 0.4).expect("add after resume");
    assert_eq!(SeriesWriter::open_existing(&path).expect("reopen").entries().len(), 4);
}

#[test]
fn series_open_existing_tolerates_missing_and_rejects_junk() {
    let dir = TempDir::new("series-junk");
    let missing = dir.path("frames.vtkhdf.series");
    assert!(SeriesWriter::open_existing(&missing).expect("missing is empty").entries().is_empty());
    fs::write(&missing, "{\"files\": [ {\"name\": \"a\", ").expect("write junk");
    let err = SeriesWriter::open_existing(&missing).err().expect("junk must not load");
    assert_eq!(err.path, missing);
}

#[test]
fn series_rejects_a_non_finite_time() {
    let dir = TempDir::new("series-nan");
    let mut series = SeriesWriter::new(&dir.path("frames.vtkhdf.series"));
    assert!(series.add("f.vtkhdf", f64::NAN).is_err());
}

fn file_size(p: &std::path::Path) -> u64 {
    fs::metadata(p).expect("metadata").len()
}

#[test]
fn compressed_frame_is_smaller_and_reads_back_equal() {
    let dir = TempDir::new("compress");
    let frame = sample_frame(5000);
    let (plain, packed) = (dir.path("plain.vtkhdf"), dir.path("packed.vtkhdf"));
    write_frame(&plain, &frame).expect("write plain");
    write_frame_as(&packed, &frame, &FrameLayout { compress: true, shared: None }).expect("write compressed");
    let (a, b) = (file_size(&plain), file_size(&packed));
    println!("5000 points: {a} bytes plain, {b} bytes compressed");
    assert!(b * 10 < a * 7, "compressed {b} bytes is not 30 % below plain {a} bytes");
    let back = read_frame(&packed).expect("read compressed");
    assert_eq!(back, frame);
    let bits = |p: &[[f32; 3]]| p.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back.points), bits(&frame.points));
}

/// Rows 3000..7000 of a sample frame kept once in `walls.vtkhdf`, the
/// `density` array per frame: the frame reads back whole, with its own
/// densities on the shared rows; without `walls.vtkhdf` it is an error that
/// names the missing file (HDF5 would read the rows as zeros).
#[test]
fn shared_rows_read_back_as_the_whole_frame() {
    let dir = TempDir::new("shared-rows");
    let mut frame = sample_frame(10_000);
    let rows = 3000..7000;
    write_frame(&dir.path("walls.vtkhdf"), &frame.rows(rows.clone())).expect("write walls");
    // The frame's densities differ from the walls file's on the shared rows.
    if let ArrayData::F32(d) = &mut frame.arrays[1].data {
        d.iter_mut().for_each(|x| *x += 1.0);
    }
    let arrays = ["velocity", "id", "kind"];
    for compress in [false, true] {
        let shared = SharedRows { file: "walls.vtkhdf", rows: rows.clone(), arrays: &arrays };
        let path = dir.path(&format!("frame_{}.vtkhdf", u8::from(compress)));
        write_frame_as(&path, &frame, &FrameLayout { compress, shared: Some(shared) }).expect("write frame");
        assert_eq!(read_frame(&path).expect("read"), frame, "compress {compress}");
        assert!(file_size(&path) < file_size(&dir.path("frame_0.vtkhdf")) || !compress);
    }
    // Without them the 4000 shared rows' points, velocity, id and kind (29
    // bytes a row, 116 kB) would be stored again; a virtual dataset's
    // mappings and the own rows' datasets take a few kB.
    write_frame(&dir.path("whole.vtkhdf"), &frame).expect("write whole");
    let (own, whole) = (file_size(&dir.path("frame_0.vtkhdf")), file_size(&dir.path("whole.vtkhdf")));
    assert!(own + 4000 * 25 <= whole, "shared rows stored again: {own} bytes, whole frame {whole}");
    let alone = TempDir::new("shared-rows-alone");
    let moved = alone.path("frame_0.vtkhdf");
    fs::copy(dir.path("frame_0.vtkhdf"), &moved).expect("copy");
    let err = read_frame(&moved).expect_err("walls.vtkhdf is missing");
    assert!(err.to_string().contains("walls.vtkhdf"), "{err}");
}

/// The phase names of a scene's `[[phase]]` tables.
fn phase_names(frame: &Frame) -> Vec<String> {
    frame.arrays.iter().filter_map(|a| a.name.strip_prefix("alpha_").map(str::to_string)).collect()
}

fn f32s<'a>(frame: &'a Frame, name: &str) -> (&'a [f32], usize) {
    let a = frame.arrays.iter().find(|a| a.name == name).unwrap_or_else(|| panic!("no array {name}"));
    match &a.data {
        ArrayData::F32(v) => (v, a.components),
        _ => panic!("{name} is not f32"),
    }
}

/// `porosph run` of a two-phase scene with walls: frames carry
/// `alpha_water`, `alpha_oil`, `beta_water`, `beta_oil` (the components of
/// `alpha` and `beta` in the scene's order), the walls are in
/// `frames/walls.vtkhdf` once, a frame reads back with them (from another
/// working directory too: `porosph render` of it draws them), and
/// `--compress` frames read back equal and smaller.
#[test]
fn run_frames_name_their_phases_and_keep_the_walls_once() {
    let dir = TempDir::new("run-frames");
    let scene = dir.path("two_phase.toml");
    fs::write(&scene, common::TWO_PHASE).expect("write scene");
    let mut frames = Vec::new();
    for compress in [false, true] {
        let out = dir.path(if compress { "packed" } else { "plain" });
        let mut args = vec![
            "run",
            common::s(&scene),
            "--out",
            common::s(&out),
            "--steps",
            "4",
            "--frame-every",
            "0.004",
            "--quiet",
        ];
        if compress {
            args.push("--compress");
        }
        let r = common::porosph(&args);
        assert!(r.status.success(), "{}", common::text(&r.stderr));
        let walls = read_frame(&out.join("frames/walls.vtkhdf")).expect("walls file");
        let path = out.join("frames/frame_00001.vtkhdf");
        let frame = read_frame(&path).expect("frame");
        assert_eq!(phase_names(&frame), ["water", "oil"]);
        for (k, phase) in ["water", "oil"].iter().enumerate() {
            for name in ["alpha", "beta"] {
                let (all, c) = f32s(&frame, name);
                let (one, _) = f32s(&frame, &format!("{name}_{phase}"));
                assert_eq!(c, 2);
                assert!(all.chunks(2).zip(one).all(|(a, b)| a[k].to_bits() == b.to_bits()), "{name}_{phase}");
            }
        }
        // The walls' rows of the frame are the walls file's points.
        let ArrayData::U8(kinds) = &frame.arrays.iter().find(|a| a.name == "kind").expect("kind").data else {
            panic!("kind is not u8")
        };
        let wall_points: Vec<[f32; 3]> =
            frame.points.iter().zip(kinds).filter(|(_, &k)| k == kind::WALL).map(|(p, _)| *p).collect();
        assert!(!wall_points.is_empty());
        assert_eq!(wall_points, walls.points);
        println!(
            "compress {compress}: frame {} bytes, walls.vtkhdf {} bytes, {} points of which {} walls",
            file_size(&path),
            file_size(&out.join("frames/walls.vtkhdf")),
            frame.points.len(),
            wall_points.len()
        );
        // Rendered from another directory: the walls are found beside the frame.
        let png = out.join("frame.png");
        let r = std::process::Command::new(env!("CARGO_BIN_EXE_porosph"))
            .args(["render", common::s(&path), "--walls", "--out", common::s(&png)])
            .current_dir(std::env::temp_dir())
            .output()
            .expect("run porosph render");
        assert!(r.status.success(), "{}", common::text(&r.stderr));
        frames.push((frame, file_size(&path)));
    }
    let ((plain, plain_bytes), (packed, packed_bytes)) = (&frames[0], &frames[1]);
    assert_eq!(plain, packed, "--compress reads back equal");
    assert!(packed_bytes < plain_bytes, "--compress: {packed_bytes} bytes, plain {plain_bytes}");
}

/// A walls-once run resumes and renders: `porosph resume` of a checkpoint
/// whose run lost `walls.vtkhdf` writes it again; the frames written after
/// the resume read back with their walls; `render --movie` draws every
/// frame and takes `walls.vtkhdf` for none.
#[test]
fn walls_once_frames_resume_and_render_as_a_movie() {
    let dir = TempDir::new("walls-resume");
    let scene = dir.path("two_phase.toml");
    fs::write(&scene, common::TWO_PHASE).expect("write scene");
    let out = dir.path("run");
    let r = common::porosph(&[
        "run",
        common::s(&scene),
        "--out",
        common::s(&out),
        "--steps",
        "4",
        "--frame-every",
        "0.004",
        "--checkpoint-every",
        "2steps",
        "--quiet",
    ]);
    assert!(r.status.success(), "{}", common::text(&r.stderr));
    let walls = out.join("frames/walls.vtkhdf");
    let wall_points = read_frame(&walls).expect("walls").points;
    fs::remove_file(&walls).expect("remove walls.vtkhdf");
    let ckpt = out.join("checkpoints/ckpt_00000002.h5");
    let r = common::porosph(&["resume", common::s(&ckpt), "--steps", "6", "--quiet"]);
    assert!(r.status.success(), "{}", common::text(&r.stderr));
    assert_eq!(read_frame(&walls).expect("walls written again").points, wall_points);
    // dt = 2 ms: to step 8, frames 0-4 (t = 0 to 16 ms), 2 of them
    // written before the checkpoint, 3 after.
    for n in 0..5 {
        let frame = read_frame(&out.join(format!("frames/frame_{n:05}.vtkhdf"))).expect("frame");
        let ArrayData::U8(kinds) = &frame.arrays.iter().find(|a| a.name == "kind").expect("kind").data else {
            panic!("kind is not u8")
        };
        let w: Vec<[f32; 3]> =
            frame.points.iter().zip(kinds).filter(|(_, &k)| k == kind::WALL).map(|(p, _)| *p).collect();
        assert_eq!(w, wall_points, "frame {n}");
    }
    let r = common::porosph(&["render", common::s(&out), "--movie", "--width", "64", "--height", "48"]);
    assert!(r.status.success(), "{}", common::text(&r.stderr));
    let mut pictures: Vec<String> = fs::read_dir(out.join("render"))
        .expect("render/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    pictures.sort();
    assert_eq!(pictures, (0..5).map(|n| format!("frame_{n:05}.png")).collect::<Vec<_>>());
}

/// The density of partly absorbed fluid particles was the whole particle's
/// mass over its faded outer volume (1.8e6 kg/m^3 at alpha_f 0.507 in
/// Example 2); it is the outer mixture's density now. A soaking sponge
/// (`common::POROUS_SOAK`) after 40 steps: every
/// fluid particle's density within 0.3 to 1.5 times the water's (below 1
/// at the free surface), walls within 0 to 1.5 times, the sponge at its 600.
#[test]
fn density_is_meaningful_for_every_kind_of_particle_regression_1e6_for_partly_absorbed() {
    let scene = common::scene_text(common::POROUS_SOAK);
    let frame = common::with_threads(2, || {
        let mut sim = Simulation::new(scene);
        for _ in 0..40 {
            sim.step().unwrap_or_else(|e| panic!("{e}"));
        }
        sim.frame()
    });
    let (density, _) = f32s(&frame, "density");
    let (alpha, _) = f32s(&frame, "alpha");
    let (beta, _) = f32s(&frame, "beta");
    let ArrayData::U8(kinds) = &frame.arrays.iter().find(|a| a.name == "kind").expect("kind").data else {
        panic!("kind is not u8")
    };
    let partly = (0..kinds.len()).filter(|&i| kinds[i] == kind::FLUID && beta[i] > 0.01 && alpha[i] < 0.99).count();
    println!("{partly} partly absorbed fluid particles");
    assert!(partly > 0, "the sponge absorbs");
    for (i, (&k, &d)) in kinds.iter().zip(density).enumerate() {
        let ok = match k {
            kind::FLUID => (300.0..=1500.0).contains(&d),
            kind::WALL => (0.0..=1500.0).contains(&d),
            _ => d == 600.0,
        };
        assert!(ok, "point {i} (kind {k}, alpha {}, beta {}): density {d}", alpha[i], beta[i]);
    }
}

/// A run written with `--compress` goes on compressing when it is resumed
/// without the option (the checkpoint keeps it): the frames written after
/// the resume equal those of an uncompressed run of the same steps and are
/// smaller.
#[test]
fn a_compressed_run_resumes_compressed() {
    let dir = TempDir::new("compress-resume");
    let scene = dir.path("two_phase.toml");
    fs::write(&scene, common::TWO_PHASE).expect("write scene");
    let run = |name: &str, compress: bool| {
        let out = dir.path(name);
        let mut args = vec!["run", common::s(&scene), "--out", common::s(&out), "--steps", "8", "--quiet"];
        args.extend(["--frame-every", "0.004", "--checkpoint-every", "2steps", "--keep", "4"]);
        if compress {
            args.push("--compress");
        }
        let r = common::porosph(&args);
        assert!(r.status.success(), "{}", common::text(&r.stderr));
        out
    };
    let (plain, packed) = (run("plain", false), run("packed", true));
    // Resume the compressed run at step 2, without --compress: frames 2-4
    // (t = 8 to 16 ms) are written again.
    let ckpt = packed.join("checkpoints/ckpt_00000002.h5");
    let r = common::porosph(&["resume", common::s(&ckpt), "--steps", "6", "--quiet"]);
    assert!(r.status.success(), "{}", common::text(&r.stderr));
    for n in 2..5 {
        let name = format!("frames/frame_{n:05}.vtkhdf");
        let (a, b) = (plain.join(&name), packed.join(&name));
        assert_eq!(read_frame(&a).expect("plain"), read_frame(&b).expect("packed"), "frame {n}");
        assert!(file_size(&b) < file_size(&a), "frame {n}: {} bytes resumed, {} plain", file_size(&b), file_size(&a));
    }
}
