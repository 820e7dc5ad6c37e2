//! VTKHDF PolyData frames: one file per frame, read by VTK's `vtkHDFReader`
//! (and so ParaView), layout as in `shared/formats/VTKHDF.md`.
//!
//! ```text
//! /                    attrs: time (f64), step (i64)       for h5py users
//! /VTKHDF              attrs: Version = int64 [2, 2], Type = "PolyData" (fixed-length ASCII)
//!   NumberOfPoints     int64 [1] = [N]
//!   Points             f32 [N, 3]
//!   Vertices/          one vertex cell per point:
//!     NumberOfCells [N], NumberOfConnectivityIds [N], Connectivity 0..N-1, Offsets 0..=N
//!   Lines/ Polygons/ Strips/   empty, but required by the reader:
//!     NumberOfCells [0], NumberOfConnectivityIds [0], Connectivity [], Offsets [0]
//!   PointData/<name>   f32 | u32 | u8, [N] (1 component) or [N, components]; attr unit
//!   FieldData/time     f64 [1]
//!   FieldData/step     int64 [1]
//! ```
//!
//! By default datasets are contiguous and uncompressed: a frame is written
//! in one pass at disk speed. With [`FrameLayout::compress`] every dataset
//! is chunked, byte-shuffled and deflated (gzip level [`DEFLATE_LEVEL`], the
//! one filter every HDF5 build and so VTK and ParaView read). PointData keeps
//! link creation order, so arrays read back in the order they were written.
//!
//! Rows stored once ([`SharedRows`], a run's static walls): the rows of
//! `Points` and of the shared PointData arrays are HDF5 virtual datasets
//! (HDF5 1.10 and later; VTK, ParaView and h5py read them as plain arrays).
//! The shared rows map to the same datasets of another frame file beside
//! this one; the frame's own rows are stored in `/OwnRows/Points` and
//! `/OwnRows/PointData/<name>` and mapped from there. The root attribute
//! `shared_rows_file` names the other file, and [`read_frame`] refuses a
//! frame whose file is missing (HDF5 would read its rows as zeros).

use super::{ArrayData, Frame, IoError, PointArray};
use hdf5::plist::group_create::LinkCreationOrder;
use hdf5::types::{FixedAscii, FixedUnicode, TypeDescriptor, VarLenAscii, VarLenUnicode};
use hdf5::types::{FloatSize, IntSize};
use hdf5::{Dataset, File, Group, H5Type, IndexType, IterationOrder, Location};
use hdf5::{Hyperslab, Selection, SliceOrIndex};
use std::fmt::{self, Display, Write as _};
use std::fs;
use std::ops::Range;
use std::path::Path;

/// VTKHDF format version written to `/VTKHDF@Version`; PolyData needs >= 2.0.
const VERSION: [i64; 2] = [2, 2];

/// The topology groups a PolyData file must have, vertices first.
const TOPOLOGIES: [&str; 4] = ["Vertices", "Lines", "Polygons", "Strips"];

/// Deflate level of compressed frames: level 4 of 9 gets most of what
/// level 9 gets from particle data at a fraction of its time.
pub const DEFLATE_LEVEL: u8 = 4;

/// Root attribute naming the file that holds a frame's shared rows.
const SHARED_ATTR: &str = "shared_rows_file";

/// Where the frame's own rows of virtual datasets are stored.
const OWN_ROWS: &str = "OwnRows";

/// How a frame is stored; the default writes every dataset contiguous and
/// uncompressed, every row in the file.
#[derive(Clone, Debug, Default)]
pub struct FrameLayout<'a> {
    /// Chunked, byte-shuffled and deflated datasets ([`DEFLATE_LEVEL`]).
    pub compress: bool,
    /// Rows kept once in another frame file beside this one.
    pub shared: Option<SharedRows<'a>>,
}

/// Rows of a frame that another frame file in the same directory holds
/// (a run's static walls: `walls.vtkhdf`, written once per run).
#[derive(Clone, Debug)]
pub struct SharedRows<'a> {
    /// That file's name, in the frame's directory; it is a frame written by
    /// [`write_frame`] whose points are these rows, in order.
    pub file: &'a str,
    /// This frame's rows that are that file's points.
    pub rows: Range<usize>,
    /// Point arrays whose values on those rows are that file's (`Points`
    /// always is); every other array is stored in full in this frame.
    pub arrays: &'a [&'a str],
}

/// Writes one frame to `path` (via a temporary name and a rename).
///
/// The file is first written to `.<name>.tmp` in the same directory, closed
/// and synced, then renamed over `path` ([`super::atomic::write_with`]): a
/// crash leaves either the old file or the new one, never a torn frame. On
/// error the temporary file is removed.
pub fn write_frame(path: &Path, frame: &Frame) -> Result<(), IoError> {
    write_frame_as(path, frame, &FrameLayout::default())
}

/// Writes one frame to `path` as [`write_frame`] does, stored as `layout`
/// says (compressed, rows shared with another file).
pub fn write_frame_as(path: &Path, frame: &Frame, layout: &FrameLayout) -> Result<(), IoError> {
    check_frame(frame).map_err(|reason| IoError::new(path, reason))?;
    if layout.compress && !hdf5::filters::deflate_available() {
        return Err(IoError::new(path, "cannot compress: this HDF5 library has no deflate (gzip) filter"));
    }
    if let Some(s) = &layout.shared {
        check_shared(frame, s).map_err(|reason| IoError::new(path, reason))?;
    }
    super::atomic::write_with(path, |tmp| write_file(tmp, frame, layout))
}

/// Reads a frame written by [`write_frame`].
///
/// Errors name the file and say what is wrong: missing file, not HDF5, not a
/// VTKHDF PolyData file, a missing dataset, a wrong shape or element type.
pub fn read_frame(path: &Path) -> Result<Frame, IoError> {
    let meta = fs::metadata(path).map_err(|e| IoError::new(path, format!("cannot read: {e}")))?;
    if !meta.is_file() {
        return Err(IoError::new(path, "not a regular file"));
    }
    let file = super::h5::open(path).map_err(|e| IoError::new(path, format!("not a readable HDF5 file: {e}")))?;
    if file.attr_names().map(|a| a.iter().any(|s| s == SHARED_ATTR)).unwrap_or(false) {
        let shared = read_string_attr(&file, SHARED_ATTR).map_err(|reason| IoError::new(path, reason))?;
        let beside = path.parent().unwrap_or(Path::new("")).join(&shared);
        if !beside.is_file() {
            return Err(IoError::new(
                path,
                format!(
                    "this frame keeps some of its points (a run's static walls) in {shared}, which is \
                     not beside it ({} is missing): copy that file with the frames",
                    beside.display()
                ),
            ));
        }
    }
    read_file(&file).map_err(|reason| IoError::new(path, reason))
}

/// A human-readable summary of a frame file, for `porosph inspect`: time,
/// step, point count, and per array its components, unit and range (per
/// component), NaN count if any, and for `kind` the points per kind.
pub fn inspect_frame(path: &Path) -> Result<String, IoError> {
    let frame = read_frame(path)?;
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = summarize(&mut s, path, &frame);
    Ok(s)
}

fn summarize(s: &mut String, path: &Path, frame: &Frame) -> fmt::Result {
    writeln!(s, "file:   {}", path.display())?;
    writeln!(s, "time:   {} s", frame.time)?;
    writeln!(s, "step:   {}", frame.step)?;
    writeln!(s, "points: {}", frame.points.len())?;
    let coords: Vec<f64> = frame.points.as_flattened().iter().map(|&x| f64::from(x)).collect();
    match bounds(&coords, 3) {
        Some((lo, hi)) => writeln!(s, "bounds: {} .. {} m", Values(&lo, true), Values(&hi, true))?,
        None => writeln!(s, "bounds: -")?,
    }
    writeln!(s, "arrays: {}", frame.arrays.len())?;
    for a in &frame.arrays {
        let unit = if a.unit.is_empty() { "-" } else { a.unit.as_str() };
        let (values, is_f32): (Vec<f64>, bool) = match &a.data {
            ArrayData::F32(v) => (v.iter().map(|&x| f64::from(x)).collect(), true),
            ArrayData::U32(v) => (v.iter().map(|&x| f64::from(x)).collect(), false),
            ArrayData::U8(v) => (v.iter().map(|&x| f64::from(x)).collect(), false),
        };
        write!(s, "  {:<16} {} x {:<3}  unit {:<8}", a.name, a.components, dtype_name(&a.data), unit)?;
        match bounds(&values, a.components) {
            Some((lo, hi)) => write!(s, "  min {}  max {}", Values(&lo, is_f32), Values(&hi, is_f32))?,
            None => write!(s, "  min -  max -")?,
        }
        let nans = values.iter().filter(|x| x.is_nan()).count();
        if nans > 0 {
            write!(s, "  NaN {nans}")?;
        }
        writeln!(s)?;
        if a.name == "kind" && a.components == 1 {
            writeln!(s, "    {}", kind_counts(&values))?;
        }
    }
    Ok(())
}

/// `fluid 500, solid 300, wall 200` (and `kind 7: 3` for unknown values).
fn kind_counts(values: &[f64]) -> String {
    let mut counts: Vec<(f64, usize)> = Vec::new();
    for &v in values {
        match counts.iter_mut().find(|(k, _)| *k == v || (k.is_nan() && v.is_nan())) {
            Some((_, c)) => *c += 1,
            None => counts.push((v, 1)),
        }
    }
    counts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let named = |k: f64| {
        if k == 0.0 {
            "fluid".to_string()
        } else if k == 1.0 {
            "solid".to_string()
        } else if k == 2.0 {
            "wall".to_string()
        } else {
            format!("kind {k}")
        }
    };
    let parts: Vec<String> = counts.iter().map(|&(k, c)| format!("{} {c}", named(k))).collect();
    if parts.is_empty() {
        "no points".to_string()
    } else {
        parts.join(", ")
    }
}

/// Per-component min and max of point-major `values`, NaN ignored; `None`
/// if there is no number at all.
fn bounds(values: &[f64], components: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let mut lo = vec![f64::INFINITY; components];
    let mut hi = vec![f64::NEG_INFINITY; components];
    for point in values.chunks_exact(components) {
        for (c, &x) in point.iter().enumerate() {
            if !x.is_nan() {
                lo[c] = lo[c].min(x);
                hi[c] = hi[c].max(x);
            }
        }
    }
    if lo.iter().zip(&hi).any(|(l, h)| l > h) {
        return None;
    }
    Some((lo, hi))
}

/// One value, or `[a, b, c]` for several; `f32` values print in their own
/// shortest form (`0.1`, not `0.10000000149011612`).
struct Values<'a>(&'a [f64], bool);

impl Display for Values<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let one = |f: &mut fmt::Formatter<'_>, x: f64| {
            // Exact: the value came from an f32.
            if self.1 {
                write!(f, "{}", x as f32)
            } else {
                write!(f, "{x}")
            }
        };
        if let [x] = self.0 {
            return one(f, *x);
        }
        f.write_str("[")?;
        for (i, &x) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            one(f, x)?;
        }
        f.write_str("]")
    }
}

fn dtype_name(data: &ArrayData) -> &'static str {
    match data {
        ArrayData::F32(_) => "f32",
        ArrayData::U32(_) => "u32",
        ArrayData::U8(_) => "u8",
    }
}

/// Rejects frames that would write an inconsistent or unreadable file.
fn check_frame(frame: &Frame) -> Result<(), String> {
    let n = frame.points.len();
    i64::try_from(frame.step).map_err(|_| format!("step {} does not fit in int64", frame.step))?;
    for (i, a) in frame.arrays.iter().enumerate() {
        if a.name.is_empty() || a.name == "." || a.name.contains('/') || a.name.contains('\0') {
            return Err(format!("array name {:?} is not a valid HDF5 dataset name", a.name));
        }
        if frame.arrays[..i].iter().any(|b| b.name == a.name) {
            return Err(format!("array name {:?} appears twice", a.name));
        }
        if a.components == 0 {
            return Err(format!("array {:?} has 0 components", a.name));
        }
        let len = match &a.data {
            ArrayData::F32(v) => v.len(),
            ArrayData::U32(v) => v.len(),
            ArrayData::U8(v) => v.len(),
        };
        if Some(len) != n.checked_mul(a.components) {
            return Err(format!(
                "array {:?} has {len} values, expected {n} points x {} components",
                a.name, a.components
            ));
        }
    }
    Ok(())
}

/// Rejects shared rows outside the frame or arrays it does not have.
fn check_shared(frame: &Frame, s: &SharedRows) -> Result<(), String> {
    if s.rows.start > s.rows.end || s.rows.end > frame.points.len() {
        return Err(format!("shared rows {:?} of a frame of {} points", s.rows, frame.points.len()));
    }
    if s.file.is_empty() || s.file.contains('/') || s.file.contains('\0') {
        return Err(format!("shared rows file {:?}: a file name in the frame's directory is needed", s.file));
    }
    if let Some(name) = s.arrays.iter().find(|n| !frame.arrays.iter().any(|a| a.name == **n)) {
        return Err(format!("shared array {name:?} is not in the frame"));
    }
    Ok(())
}

/// Adds what was being done to an HDF5 error.
trait Context<T> {
    fn ctx(self, what: impl Display) -> Result<T, String>;
}

impl<T> Context<T> for hdf5::Result<T> {
    fn ctx(self, what: impl Display) -> Result<T, String> {
        self.map_err(|e| format!("{what}: {e}"))
    }
}

fn write_file(tmp: &Path, frame: &Frame, layout: &FrameLayout) -> Result<(), String> {
    let file = super::h5::create(tmp).ctx(format_args!("cannot create {}", tmp.display()))?;
    write_contents(&file, frame, layout)?;
    // Closing flushes: a full disk may only show up here.
    file.close().ctx(format_args!("cannot close {}", tmp.display()))
}

fn write_contents(file: &File, frame: &Frame, layout: &FrameLayout) -> Result<(), String> {
    let n = frame.points.len();
    let n_ids = n as i64;
    // Checked in check_frame.
    let step = frame.step as i64;
    let compress = layout.compress;

    write_scalar_attr(file, "time", &frame.time)?;
    write_scalar_attr(file, "step", &step)?;
    let own = match &layout.shared {
        Some(s) => {
            let name: VarLenUnicode = s.file.parse().map_err(|e| format!("shared rows file {:?}: {e}", s.file))?;
            write_scalar_attr(file, SHARED_ATTR, &name)?;
            let own = file.create_group(OWN_ROWS).ctx(format_args!("cannot create /{OWN_ROWS}"))?;
            own.create_group("PointData").ctx(format_args!("cannot create /{OWN_ROWS}/PointData"))?;
            Some((own, s))
        }
        None => None,
    };
    // The rows of `Points` (`array` None) and of the shared arrays.
    let rows = |array: Option<&str>, path: &str| {
        own.as_ref().filter(|(_, s)| array.is_none_or(|a| s.arrays.contains(&a))).map(|(g, s)| Rows {
            own: g,
            own_path: format!("/{OWN_ROWS}/{path}"),
            shared: s,
            shared_path: format!("/VTKHDF/{path}"),
        })
    };

    let vtk = file.create_group("VTKHDF").ctx("cannot create /VTKHDF")?;
    vtk.new_attr_builder().with_data(&VERSION[..]).create("Version").ctx("cannot write /VTKHDF@Version")?;
    let poly_data = FixedAscii::<8>::from_ascii("PolyData").map_err(|e| e.to_string())?;
    vtk.new_attr::<FixedAscii<8>>()
        .shape(())
        .create("Type")
        .and_then(|a| a.as_writer().write_scalar(&poly_data))
        .ctx("cannot write /VTKHDF@Type")?;

    write_dataset(&vtk, "NumberOfPoints", &[n_ids], &[1], false)?;
    write_point_dataset(&vtk, "Points", frame.points.as_flattened(), &[n, 3], compress, rows(None, "Points"))?;

    for topology in TOPOLOGIES {
        let g = vtk.create_group(topology).ctx(format_args!("cannot create /VTKHDF/{topology}"))?;
        // One vertex cell per point; the other topologies are empty.
        let cells = if topology == "Vertices" { n } else { 0 };
        let cells_i64 = cells as i64;
        let connectivity: Vec<i64> = (0..cells_i64).collect();
        let offsets: Vec<i64> = (0..=cells_i64).collect();
        write_dataset(&g, "NumberOfCells", &[cells_i64], &[1], false)?;
        write_dataset(&g, "NumberOfConnectivityIds", &[cells_i64], &[1], false)?;
        write_dataset(&g, "Connectivity", &connectivity, &[cells], compress)?;
        write_dataset(&g, "Offsets", &offsets, &[cells + 1], compress)?;
    }

    let point_data = vtk
        .create_group_builder()
        .with_gcpl(|p| p.link_creation_order(LinkCreationOrder::Indexed))
        .create("PointData")
        .ctx("cannot create /VTKHDF/PointData")?;
    for a in &frame.arrays {
        let shape: &[usize] = if a.components == 1 { &[n] } else { &[n, a.components] };
        let r = || rows(Some(&a.name), &format!("PointData/{}", a.name));
        let ds = match &a.data {
            ArrayData::F32(v) => write_point_dataset(&point_data, &a.name, v, shape, compress, r())?,
            ArrayData::U32(v) => write_point_dataset(&point_data, &a.name, v, shape, compress, r())?,
            ArrayData::U8(v) => write_point_dataset(&point_data, &a.name, v, shape, compress, r())?,
        };
        let unit: VarLenUnicode = a.unit.parse().map_err(|e| format!("unit of {:?}: {e}", a.name))?;
        write_scalar_attr(&ds, "unit", &unit)?;
    }

    let field_data = vtk.create_group("FieldData").ctx("cannot create /VTKHDF/FieldData")?;
    write_dataset(&field_data, "time", &[frame.time], &[1], false)?;
    write_dataset(&field_data, "step", &[step], &[1], false)?;
    Ok(())
}

fn write_scalar_attr<T: H5Type>(loc: &Location, name: &str, value: &T) -> Result<(), String> {
    loc.new_attr::<T>()
        .shape(())
        .create(name)
        .and_then(|a| a.as_writer().write_scalar(value))
        .ctx(format_args!("cannot write attribute {}@{name}", loc.name()))
}

/// Values per chunk of a compressed dataset (256 KiB of f32).
const CHUNK_VALUES: usize = 1 << 16;

/// A dataset of `shape` holding `data` (row-major): contiguous, or with
/// `compress` chunked by rows, shuffled and deflated.
fn write_dataset<T: H5Type>(
    group: &Group,
    name: &str,
    data: &[T],
    shape: &[usize],
    compress: bool,
) -> Result<Dataset, String> {
    let what = || format!("cannot write {}/{name}", group.name());
    let mut builder = group.new_dataset::<T>();
    if compress && !data.is_empty() {
        let row: usize = shape[1..].iter().product::<usize>().max(1);
        let mut chunk = shape.to_vec();
        chunk[0] = (CHUNK_VALUES / row).clamp(1, shape[0]);
        builder = builder.chunk(chunk).shuffle().deflate(DEFLATE_LEVEL);
    }
    let ds = builder.shape(shape).create(name).ctx(what())?;
    if !data.is_empty() {
        ds.as_writer().write_raw(data).ctx(what())?;
    }
    Ok(ds)
}

/// A point dataset whose shared rows are another file's.
struct Rows<'a> {
    /// `/OwnRows`, where the frame's own rows go.
    own: &'a Group,
    /// The dataset of the own rows, from the root.
    own_path: String,
    shared: &'a SharedRows<'a>,
    /// The dataset in the shared file, from its root.
    shared_path: String,
}

/// Rows `rows` of a dataset of `shape` (all of its other dimensions).
fn row_selection(rows: Range<usize>, shape: &[usize]) -> Selection {
    let mut s = vec![SliceOrIndex::from(rows)];
    s.extend(shape[1..].iter().map(|&c| SliceOrIndex::from(0..c)));
    Selection::from(Hyperslab::from(s))
}

/// A point dataset (one row per point): as [`write_dataset`], or with
/// `rows` a virtual dataset whose shared rows map to the shared file and
/// whose other rows are stored in `/OwnRows` (module doc).
fn write_point_dataset<T: H5Type + Copy>(
    group: &Group,
    name: &str,
    data: &[T],
    shape: &[usize],
    compress: bool,
    rows: Option<Rows>,
) -> Result<Dataset, String> {
    let Some(r) = rows else {
        return write_dataset(group, name, data, shape, compress);
    };
    let row: usize = shape[1..].iter().product();
    let (n, shared) = (shape[0], r.shared.rows.clone());
    let (before, len) = (shared.start, shared.len());
    let mut own_values = Vec::with_capacity(data.len() - len * row);
    own_values.extend_from_slice(&data[..before * row]);
    own_values.extend_from_slice(&data[shared.end * row..]);
    let own_n = n - len;
    let mut own_shape = shape.to_vec();
    own_shape[0] = own_n;
    let own_group = if r.own_path.contains("/PointData/") {
        r.own.group("PointData").ctx(format_args!("cannot open /{OWN_ROWS}/PointData"))?
    } else {
        r.own.clone()
    };
    write_dataset(&own_group, name, &own_values, &own_shape, compress)?;
    let mut shared_shape = shape.to_vec();
    shared_shape[0] = len;
    let mut builder = group.new_dataset::<T>().shape(shape);
    if before > 0 {
        let sel = row_selection(0..before, shape);
        builder = builder.virtual_map(".", &r.own_path, own_shape.clone(), sel.clone(), shape.to_vec(), sel);
    }
    if shared.end < n {
        builder = builder.virtual_map(
            ".",
            &r.own_path,
            own_shape.clone(),
            row_selection(before..own_n, shape),
            shape.to_vec(),
            row_selection(shared.end..n, shape),
        );
    }
    if len > 0 {
        builder = builder.virtual_map(
            r.shared.file,
            &r.shared_path,
            shared_shape,
            row_selection(0..len, shape),
            shape.to_vec(),
            row_selection(shared, shape),
        );
    }
    builder.create(name).ctx(format_args!("cannot write {}/{name} (virtual)", group.name()))
}

fn read_file(file: &File) -> Result<Frame, String> {
    let vtk = file.group("VTKHDF").map_err(|_| "no /VTKHDF group: not a VTKHDF file".to_string())?;
    let kind = read_string_attr(&vtk, "Type")?;
    if kind != "PolyData" {
        return Err(format!("/VTKHDF@Type is {kind:?}, expected \"PolyData\""));
    }

    let points_ds = open_dataset(&vtk, "Points")?;
    let n = match points_ds.shape()[..] {
        [n, 3] => n,
        ref shape => return Err(format!("/VTKHDF/Points has shape {shape:?}, expected [N, 3]")),
    };
    let flat: Vec<f32> = read_values(&points_ds, "/VTKHDF/Points", Element::Float)?;
    let points = flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();

    let counts: Vec<i64> = read_values(&open_dataset(&vtk, "NumberOfPoints")?, "/VTKHDF/NumberOfPoints", Element::Int)?;
    if counts.iter().sum::<i64>() != n as i64 {
        return Err(format!("/VTKHDF/NumberOfPoints is {counts:?} but Points has {n} rows"));
    }

    let mut arrays = Vec::new();
    if vtk.link_exists("PointData") {
        let point_data = vtk.group("PointData").ctx("cannot open /VTKHDF/PointData")?;
        let names = point_data
            .member_names_by(IndexType::CreationOrder, IterationOrder::Increasing)
            .or_else(|_| point_data.member_names())
            .ctx("cannot list /VTKHDF/PointData")?;
        for name in names {
            arrays.push(read_array(&point_data, &name, n)?);
        }
    }

    let field_data = vtk.group("FieldData").map_err(|_| "no /VTKHDF/FieldData group (time and step)".to_string())?;
    let time = read_single::<f64>(&field_data, "time", Element::Float)?;
    let step = read_single::<i64>(&field_data, "step", Element::Int)?;
    let step = u64::try_from(step).map_err(|_| format!("/VTKHDF/FieldData/step is {step}"))?;

    Ok(Frame { time, step, points, arrays })
}

fn open_dataset(group: &Group, name: &str) -> Result<Dataset, String> {
    group.dataset(name).map_err(|_| format!("missing dataset {}/{name}", group.name()))
}

/// The element class a dataset must have to be read as a given Rust type.
#[derive(Clone, Copy)]
enum Element {
    Float,
    Int,
}

/// Reads all values of `ds` as `T`, converting within the element class only.
fn read_values<T: H5Type>(ds: &Dataset, what: &str, class: Element) -> Result<Vec<T>, String> {
    let desc = ds.dtype().and_then(|t| t.to_descriptor()).ctx(format_args!("{what}: element type"))?;
    let ok = match class {
        Element::Float => matches!(desc, TypeDescriptor::Float(_)),
        Element::Int => matches!(desc, TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)),
    };
    if !ok {
        return Err(format!("{what} has element type {desc}"));
    }
    ds.read_raw::<T>().ctx(format_args!("cannot read {what}"))
}

/// Reads a one-value dataset (shape [1] or scalar).
fn read_single<T: H5Type + Copy>(group: &Group, name: &str, class: Element) -> Result<T, String> {
    let what = format!("{}/{name}", group.name());
    let ds = open_dataset(group, name)?;
    if ds.size() != 1 {
        return Err(format!("{what} has shape {:?}, expected [1]", ds.shape()));
    }
    let v: Vec<T> = read_values(&ds, &what, class)?;
    v.first().copied().ok_or_else(|| format!("{what} is empty"))
}

fn read_array(group: &Group, name: &str, n: usize) -> Result<PointArray, String> {
    let what = format!("/VTKHDF/PointData/{name}");
    let ds = open_dataset(group, name)?;
    let components = match ds.shape()[..] {
        [rows] if rows == n => 1,
        [rows, c] if rows == n && c > 0 => c,
        ref shape => return Err(format!("{what} has shape {shape:?}, expected [{n}] or [{n}, components]")),
    };
    let desc = ds.dtype().and_then(|t| t.to_descriptor()).ctx(format_args!("{what}: element type"))?;
    let data = match desc {
        TypeDescriptor::Float(FloatSize::U4) => ArrayData::F32(ds.read_raw().ctx(&what)?),
        TypeDescriptor::Unsigned(IntSize::U4) => ArrayData::U32(ds.read_raw().ctx(&what)?),
        TypeDescriptor::Unsigned(IntSize::U1) => ArrayData::U8(ds.read_raw().ctx(&what)?),
        other => return Err(format!("{what} has element type {other}, expected f32, u32 or u8")),
    };
    let unit = if ds.attr_names().map(|a| a.iter().any(|s| s == "unit")).unwrap_or(false) {
        read_string_attr(&ds, "unit")?
    } else {
        String::new()
    };
    Ok(PointArray { name: name.to_string(), unit, components, data })
}

/// Reads a string attribute stored as any HDF5 string type (fixed or
/// variable length, ASCII or UTF-8), scalar or of shape [1].
fn read_string_attr(loc: &Location, name: &str) -> Result<String, String> {
    let what = format!("{}@{name}", loc.name());
    let attr = loc.attr(name).map_err(|_| format!("missing attribute {what}"))?;
    let desc = attr.dtype().and_then(|t| t.to_descriptor()).ctx(&what)?;
    let first = |v: Vec<String>| v.into_iter().next().ok_or_else(|| format!("{what} is empty"));
    match desc {
        TypeDescriptor::FixedAscii(_) => {
            let v: Vec<FixedAscii<1024>> = attr.read_raw().ctx(&what)?;
            first(v.iter().map(|s| s.as_str().to_string()).collect())
        }
        TypeDescriptor::FixedUnicode(_) => {
            let v: Vec<FixedUnicode<1024>> = attr.read_raw().ctx(&what)?;
            first(v.iter().map(|s| s.as_str().to_string()).collect())
        }
        TypeDescriptor::VarLenAscii => {
            let v: Vec<VarLenAscii> = attr.read_raw().ctx(&what)?;
            first(v.iter().map(|s| s.as_str().to_string()).collect())
        }
        TypeDescriptor::VarLenUnicode => {
            let v: Vec<VarLenUnicode> = attr.read_raw().ctx(&what)?;
            first(v.iter().map(|s| s.as_str().to_string()).collect())
        }
        other => Err(format!("{what} has type {other}, expected a string")),
    }
}
