//! Frame files (VTKHDF) and the series index: what is written reads back
//! exactly, writes are atomic, and bad files give errors, not panics.

use porosph::io::{inspect_frame, read_frame, write_frame, ArrayData, Frame, PointArray, SeriesWriter};
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
