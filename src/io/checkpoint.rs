//! Checkpoints: the complete state of a run in one HDF5 file, written so
//! that a crash never leaves a torn file, read back so that a resumed run is
//! bit for bit the run that was saved, and checked so that a damaged file is
//! an error that says what is wrong, never a panic or a silently wrong run.
//!
//! ```text
//! /                   attrs: format = "porosph checkpoint", format_version (u32),
//!                            time (f64, s), step (u64), dt (f32, s),
//!                            fluid_particles (u64), wall_particles (u64),
//!                            solid_particles (u64),
//!                            failure (string; "" unless written when a step failed)
//! /scene              u8 [n]: the scene text as run (UTF-8): as read, mesh paths made absolute; attrs origin, xxh64
//! /params             attrs: the parameters porosph derived from the scene
//!                     (h, kernel_support, gravity, max_dt, cfl, ...), units
//! /run                attrs: where the run stands (frames written, next frame
//!                     time, stop time or step, checkpoint schedule, keep,
//!                     compress: 1 if the frames are compressed), porosph_version
//! /fluid/<name>       one dataset per registered fluid array: f32 or u32 [N],
//!                     per-phase arrays f32 [K, N]; attrs unit, xxh64
//! /walls/<name>       the same for the wall store, [N_walls]
//! /solids/<name>      the same for the solid store, [N_solids] (the rest
//!                     data of the elastic model, SS0, V0 and L, is rebuilt
//!                     from the rest positions on load)
//! ```
//!
//! Every dataset carries `xxh64`, the XXH64 (seed 0) of its little-endian
//! bytes as stored (h5py: `xxhash.xxh64(ds[()].tobytes()).intdigest()`), and
//! every dataset is read back through its checksum. The file is written with
//! the HDF5 1.8 object format, whose metadata (superblock, object headers and
//! so the scalar attributes) carries HDF5's own checksums. Strings are
//! fixed-length (h5py gives `bytes`: `f.attrs["format"].decode()`), and the
//! scene text is a byte dataset (`f["scene"][()].tobytes().decode()`):
//! variable-length strings would live in HDF5's global heap, which has no
//! checksum, and a damaged heap crashed the HDF5 library in our tests.
//!
//! The particle arrays come from the stores' field registry
//! ([`FluidStore::for_each_column`]): an array added to a store later is
//! saved and restored with no change here (a file from before it then lacks
//! that dataset, and reading it is an error rather than a silent default;
//! the exceptions are the fractions' low parts, `alpha_lo` and `beta_lo`,
//! and the granular solids' state, `sxx` .. `plastic_strain`, which an
//! older run did not have, so 0 is its exact state).
//! Datasets are contiguous and uncompressed, so a checkpoint is written at
//! disk speed; a reader can also take the bytes straight from a memory map
//! ([`ReadMethod::Mmap`]), which measured no faster (bench/RESULTS.md).

use super::xxh64::Xxh64;
use super::IoError;
use crate::pipeline::{Params, SavedState, Simulation};
use crate::scene::Scene;
use crate::store::{Column, ColumnMut, FluidStore, SolidStore, WallStore};
use hdf5::dataset::Layout;
use hdf5::types::{FixedUnicode, TypeDescriptor};
use hdf5::{Dataset, File, Group, H5Type, Location};
use std::fmt::{self, Display, Write as _};
use std::fs;
use std::path::Path;

/// The fluid's low parts of the fractions (`FluidStore::alpha_lo`), which
/// files written before them lack; they read as 0 there.
const LOW_PARTS: [&str; 2] = ["alpha_lo", "beta_lo"];

/// The granular solids' state (`SolidStore::sxx` .. `plastic_strain`),
/// which files written before granular solids existed lack; their solids
/// were all elastic, where it is 0.
const GRANULAR_STATE: [&str; 7] = ["sxx", "syy", "szz", "sxy", "sxz", "syz", "plastic_strain"];

/// The value of the root attribute `format`.
pub const FORMAT: &str = "porosph checkpoint";

/// The checkpoint format this porosph writes and reads. Raise it whenever
/// the meaning of a stored item changes (not when an array is added: the
/// registry takes care of that, and an older file then misses a dataset).
pub const FORMAT_VERSION: u32 = 1;

/// Where a run stands, beyond the simulation state: what `porosph resume`
/// needs to continue the run's frames, stop condition and checkpoints.
#[derive(Clone, Debug, PartialEq)]
pub struct RunInfo {
    /// Frames written so far: the number of the next frame.
    pub frames_written: u64,
    /// Simulated time at which the next frame is due, s.
    pub next_frame_time: f64,
    /// Simulated time between frames, s.
    pub frame_every: f64,
    /// The run stops at this simulated time, s (if it stops by time).
    pub stop_time: Option<f64>,
    /// The run stops after this step (if it stops by step count).
    pub stop_step: Option<u64>,
    /// The checkpoint schedule in the form `--checkpoint-every` reads
    /// (`0.1s`, `500steps`); empty if the run wrote none.
    pub checkpoint_every: String,
    /// Checkpoints kept.
    pub keep: u32,
    /// Frames compressed (`--compress`); absent in checkpoints written
    /// before it was stored, read as false.
    pub compress: bool,
}

/// A checkpoint read back: the simulation state and where the run stood.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkpoint {
    pub format_version: u32,
    pub state: SavedState,
    pub run: RunInfo,
    /// Why the run failed, for a diagnostic checkpoint written when a step
    /// failed (NaN, explosion); `None` for a regular checkpoint.
    pub failure: Option<String>,
}

/// How [`read_checkpoint_with`] takes the particle arrays from the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadMethod {
    /// HDF5 reads every dataset (`H5Dread`).
    Hdf5,
    /// The file is memory-mapped and each contiguous dataset's bytes are
    /// checked and copied straight from the map (HDF5 reads only metadata).
    Mmap,
}

/// The method [`read_checkpoint`] uses (see bench/RESULTS.md, "Checkpoints").
pub const DEFAULT_READ: ReadMethod = ReadMethod::Hdf5;

/// One dataset's checksum: stored in the file and computed from its data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DatasetCheck {
    /// Dataset path in the file, e.g. `/fluid/ux`.
    pub name: String,
    pub stored: u64,
    pub computed: u64,
}

impl DatasetCheck {
    /// Whether the data matches its checksum.
    pub fn holds(&self) -> bool {
        self.stored == self.computed
    }
}

impl Display for DatasetCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "dataset {} is corrupt: its data hashes to XXH64 {:#018x}, the file recorded {:#018x}",
            self.name, self.computed, self.stored
        )
    }
}

// ---------------------------------------------------------------- writing

/// Writes the state of `sim` and `run` to `path`, atomically.
///
/// The file is first written to `.<name>.tmp` in the same directory, closed
/// (HDF5 flushes), synced to disk, and only then renamed over `path`; the
/// directory is synced after the rename ([`super::atomic::write_with`]). A
/// crash at any moment leaves either no file or a complete one at `path`. On
/// error (unwritable directory, full disk) the temporary file is removed and
/// nothing else is touched.
///
/// `failure` marks a diagnostic checkpoint written when a step failed.
pub fn write_checkpoint(path: &Path, sim: &Simulation, run: &RunInfo, failure: Option<&str>) -> Result<(), IoError> {
    super::atomic::write_with(path, |tmp| write_file(tmp, sim, run, failure))
}

/// `.<file name>.tmp` next to `path`: the name a checkpoint has while it is
/// being written.
pub use super::atomic::temp_path;

/// Adds what was being done to an HDF5 error.
trait Context<T> {
    fn ctx(self, what: impl Display) -> Result<T, String>;
}

impl<T> Context<T> for hdf5::Result<T> {
    fn ctx(self, what: impl Display) -> Result<T, String> {
        self.map_err(|e| format!("{what}: {e}"))
    }
}

fn write_file(tmp: &Path, sim: &Simulation, run: &RunInfo, failure: Option<&str>) -> Result<(), String> {
    let file = super::h5::create_v18(tmp).ctx(format_args!("cannot create {}", tmp.display()))?;
    write_contents(&file, sim, run, failure)?;
    // Closing flushes: a full disk may only show up here.
    file.close().ctx(format_args!("cannot close {}", tmp.display()))
}

fn write_contents(file: &File, sim: &Simulation, run: &RunInfo, failure: Option<&str>) -> Result<(), String> {
    write_str_attr(file, "format", FORMAT)?;
    write_attr(file, "format_version", &FORMAT_VERSION)?;
    write_attr(file, "time", &sim.time)?;
    write_attr(file, "step", &sim.step)?;
    write_attr(file, "dt", &sim.dt)?;
    write_attr(file, "fluid_particles", &(sim.fluid.len() as u64))?;
    write_attr(file, "wall_particles", &(sim.walls.len() as u64))?;
    write_attr(file, "solid_particles", &(sim.solids.len() as u64))?;
    write_str_attr(file, "failure", failure.unwrap_or(""))?;

    let text = sim.scene.text.as_bytes();
    let scene = dataset(file, "scene", text, &[text.len()]).ctx("cannot write /scene")?;
    write_str_attr(&scene, "origin", &sim.scene.origin)?;
    write_attr(&scene, "xxh64", &scene_hash(&sim.scene.text))?;

    let params = file.create_group("params").ctx("cannot create /params")?;
    for (name, value) in param_values(&sim.params) {
        match value {
            Value::F32(v) => write_attr(&params, name, &v)?,
            Value::U32(v) => write_attr(&params, name, &v)?,
            Value::F32s(v) => params
                .new_attr_builder()
                .with_data(&v[..])
                .create(name)
                .map(drop)
                .ctx(format_args!("cannot write /params@{name}"))?,
        }
    }
    let names: Vec<FixedUnicode<NAME_CAP>> =
        sim.scene.phases.iter().map(|p| fixed::<NAME_CAP>(&p.name)).collect::<Result<_, _>>()?;
    let longest = names.iter().map(|n| n.len()).max().unwrap_or(0).max(1);
    params
        .new_attr_builder()
        .with_data_as(&names[..], TypeDescriptor::FixedUnicode(longest))
        .create("phase_names")
        .ctx("cannot write /params@phase_names")?;
    write_str_attr(&params, "units", PARAM_UNITS)?;

    let g = file.create_group("run").ctx("cannot create /run")?;
    write_attr(&g, "frames_written", &run.frames_written)?;
    write_attr(&g, "next_frame_time", &run.next_frame_time)?;
    write_attr(&g, "frame_every", &run.frame_every)?;
    if let Some(t) = run.stop_time {
        write_attr(&g, "stop_time", &t)?;
    }
    if let Some(s) = run.stop_step {
        write_attr(&g, "stop_step", &s)?;
    }
    write_str_attr(&g, "checkpoint_every", &run.checkpoint_every)?;
    write_attr(&g, "keep", &run.keep)?;
    write_attr(&g, "compress", &u8::from(run.compress))?;
    write_str_attr(&g, "porosph_version", env!("CARGO_PKG_VERSION"))?;

    let fluid = file.create_group("fluid").ctx("cannot create /fluid")?;
    write_attr(&fluid, "particles", &(sim.fluid.len() as u64))?;
    let mut result = Ok(());
    sim.fluid.for_each_column(|name, unit, c| {
        if result.is_ok() {
            result = write_column(&fluid, name, unit, c, sim.fluid.len());
        }
    });
    result.clone()?;
    let walls = file.create_group("walls").ctx("cannot create /walls")?;
    write_attr(&walls, "particles", &(sim.walls.len() as u64))?;
    sim.walls.for_each_column(|name, unit, c| {
        if result.is_ok() {
            result = write_column(&walls, name, unit, c, sim.walls.len());
        }
    });
    result.clone()?;
    let solids = file.create_group("solids").ctx("cannot create /solids")?;
    write_attr(&solids, "particles", &(sim.solids.len() as u64))?;
    sim.solids.for_each_column(|name, unit, c| {
        if result.is_ok() {
            result = write_column(&solids, name, unit, c, sim.solids.len());
        }
    });
    result
}

/// Writes one registered column as a contiguous dataset with its unit and
/// checksum.
fn write_column(group: &Group, name: &str, unit: &str, c: Column<'_>, n: usize) -> Result<(), String> {
    let what = || format!("cannot write {}/{name}", group.name());
    let mut h = Xxh64::new(0);
    let ds = match c {
        Column::F32(v) => {
            h.update_f32(v);
            dataset(group, name, v, &[v.len()]).ctx(what())?
        }
        Column::U32(v) => {
            h.update_u32(v);
            dataset(group, name, v, &[v.len()]).ctx(what())?
        }
        Column::PerPhase(vs) => {
            let mut flat = Vec::with_capacity(vs.len() * n);
            for v in vs {
                if v.len() != n {
                    return Err(format!("{}/{name} has a phase with {} values, expected {n}", group.name(), v.len()));
                }
                flat.extend_from_slice(v);
            }
            h.update_f32(&flat);
            dataset(group, name, &flat, &[vs.len(), n]).ctx(what())?
        }
    };
    write_str_attr(&ds, "unit", unit)?;
    write_attr(&ds, "xxh64", &h.finish())
}

fn dataset<T: H5Type>(group: &Group, name: &str, data: &[T], shape: &[usize]) -> hdf5::Result<Dataset> {
    let ds = group.new_dataset::<T>().shape(shape).create(name)?;
    if !data.is_empty() {
        ds.as_writer().write_raw(data)?;
    }
    Ok(ds)
}

fn write_attr<T: H5Type>(loc: &Location, name: &str, value: &T) -> Result<(), String> {
    loc.new_attr::<T>()
        .shape(())
        .create(name)
        .and_then(|a| a.as_writer().write_scalar(value))
        .ctx(format_args!("cannot write attribute {}", attr_name(loc, name)))
}

/// Longest string attribute, bytes (longer ones, such as a very long scene
/// origin, are cut at a character boundary).
const STR_CAP: usize = 4096;

/// Longest phase name stored in `/params@phase_names`, bytes.
const NAME_CAP: usize = 256;

/// `value` as a fixed-length string of capacity `N`, cut to fit.
fn fixed<const N: usize>(value: &str) -> Result<FixedUnicode<N>, String> {
    let mut end = value.len().min(N);
    while !value.is_char_boundary(end) {
        end -= 1;
    }
    value[..end].parse::<FixedUnicode<N>>().map_err(|e| format!("string {value:?}: {e}"))
}

/// A string attribute, stored as a fixed-length UTF-8 string of its own
/// length: fixed-length strings live in the object header, which HDF5
/// checksums (variable-length ones would live in the global heap, which has
/// no checksum, and a damaged heap can crash the HDF5 library).
fn write_str_attr(loc: &Location, name: &str, value: &str) -> Result<(), String> {
    let v = fixed::<STR_CAP>(value)?;
    loc.new_attr_builder()
        .empty_as(TypeDescriptor::FixedUnicode(v.len().max(1)))
        .shape(())
        .create(name)
        .and_then(|a| a.as_writer().write_scalar(&v))
        .ctx(format_args!("cannot write attribute {}", attr_name(loc, name)))
}

/// `/group@name`, or `/@name` at the root.
fn attr_name(loc: &Location, name: &str) -> String {
    format!("{}@{name}", loc.name())
}

/// XXH64 of the scene text's UTF-8 bytes.
fn scene_hash(text: &str) -> u64 {
    let mut h = Xxh64::new(0);
    h.update(text.as_bytes());
    h.finish()
}

/// A parameter value as stored in `/params`.
#[derive(Clone, Debug, PartialEq)]
enum Value {
    F32(f32),
    U32(u32),
    F32s(Vec<f32>),
}

impl Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::F32(v) => write!(f, "{v}"),
            Value::U32(v) => write!(f, "{v}"),
            Value::F32s(v) => write!(f, "{v:?}"),
        }
    }
}

/// Units of the `/params` attributes, stored as `/params@units`.
const PARAM_UNITS: &str = "h: m, kernel_support: m, gravity: m/s^2, max_dt: s, \
     phase_density: kg/m^3, phase_viscosity: Pa s; cfl, max_density_error (fraction), \
     min_iterations, max_iterations, omega: dimensionless";

/// The stored parameters, by name; written, and compared on reading with
/// the parameters derived from the stored scene.
fn param_values(p: &Params) -> Vec<(&'static str, Value)> {
    vec![
        ("h", Value::F32(p.h)),
        ("kernel_support", Value::F32(p.kernel.support)),
        ("gravity", Value::F32s(p.gravity.to_vec())),
        ("max_dt", Value::F32(p.max_dt)),
        ("cfl", Value::F32(p.cfl)),
        ("max_density_error", Value::F32(p.max_density_error)),
        ("min_iterations", Value::U32(p.min_iterations)),
        ("max_iterations", Value::U32(p.max_iterations)),
        ("omega", Value::F32(p.omega)),
        ("phase_density", Value::F32s(p.phase_density.clone())),
        ("phase_viscosity", Value::F32s(p.phase_viscosity.clone())),
    ]
}

// ---------------------------------------------------------------- reading

/// Reads a checkpoint written by [`write_checkpoint`], checking every
/// dataset against its checksum.
///
/// Errors name the file and say what is wrong: missing or unreadable file,
/// not HDF5 or truncated, not a checkpoint, another format version, a
/// missing or unknown dataset, a wrong shape or element type, a checksum
/// that does not hold, or parameters that differ from those of the stored
/// scene.
pub fn read_checkpoint(path: &Path) -> Result<Checkpoint, IoError> {
    read_checkpoint_with(path, DEFAULT_READ)
}

/// [`read_checkpoint`] with a chosen way of reading the particle arrays.
pub fn read_checkpoint_with(path: &Path, method: ReadMethod) -> Result<Checkpoint, IoError> {
    let file = open(path)?;
    let mut r = Reader::new(path, &file, method, true)?;
    r.read().map_err(|reason| IoError::new(path, reason))
}

/// Reads a checkpoint and rebuilds the simulation it holds, ready to step,
/// with where the run stood. (A diagnostic checkpoint loads too; its
/// `failure` is in [`read_checkpoint`]'s result.)
pub fn load_checkpoint(path: &Path) -> Result<(Simulation, RunInfo), IoError> {
    let Checkpoint { state, run, .. } = read_checkpoint(path)?;
    let sim = Simulation::from_saved_state(state).map_err(|e| IoError::new(path, e))?;
    Ok((sim, run))
}

/// What a file is, judged by its content rather than its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// A VTKHDF frame (`/VTKHDF`).
    Frame,
    /// A porosph checkpoint (root attribute `format`).
    Checkpoint,
}

/// Whether `path` holds a frame or a checkpoint; an error names the file
/// and says why it is neither.
pub fn file_kind(path: &Path) -> Result<FileKind, IoError> {
    let file = open(path)?;
    if file.link_exists("VTKHDF") {
        return Ok(FileKind::Frame);
    }
    if file.attr("format").is_ok() {
        return Ok(FileKind::Checkpoint);
    }
    Err(IoError::new(
        path,
        "an HDF5 file, but neither a porosph frame (no /VTKHDF) nor a checkpoint (no format attribute)",
    ))
}

fn open(path: &Path) -> Result<File, IoError> {
    let meta = fs::metadata(path).map_err(|e| IoError::new(path, format!("cannot read: {e}")))?;
    if !meta.is_file() {
        return Err(IoError::new(path, "not a regular file"));
    }
    super::h5::open(path)
        .map_err(|e| IoError::new(path, format!("not a readable HDF5 file (truncated or damaged?): {e}")))
}

/// What [`inspect_checkpoint`] found.
#[derive(Clone, Debug)]
pub struct Inspection {
    /// The human-readable report.
    pub text: String,
    /// Whether every dataset matches its checksum.
    pub checksums_hold: bool,
}

/// A report on a checkpoint for `porosph inspect`: format version, time,
/// step, dt, particle counts, per-phase fluid volume, where the run stood,
/// and whether every checksum holds (all datasets are checked, and each
/// one that fails is named).
pub fn inspect_checkpoint(path: &Path) -> Result<Inspection, IoError> {
    let file = open(path)?;
    let mut r = Reader::new(path, &file, DEFAULT_READ, false)?;
    let ckpt = r.read().map_err(|reason| IoError::new(path, reason))?;
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = summarize(&mut s, path, &ckpt, &r.checks);
    Ok(Inspection { text: s, checksums_hold: r.checks.iter().all(DatasetCheck::holds) })
}

/// Outer and inner volume of each phase, m^3: sums over fluid particles of
/// h^3 alpha_k and h^3 beta_k (h = particle spacing; P §6.1).
pub fn phase_volumes(state: &SavedState) -> (Vec<f64>, Vec<f64>) {
    let h = f64::from(state.scene.simulation.particle_spacing);
    state.fluid.phase_volumes(h * h * h)
}

fn summarize(s: &mut String, path: &Path, c: &Checkpoint, checks: &[DatasetCheck]) -> fmt::Result {
    let st = &c.state;
    writeln!(s, "file:       {}", path.display())?;
    writeln!(s, "kind:       porosph checkpoint, format version {}", c.format_version)?;
    if let Some(f) = &c.failure {
        writeln!(s, "diagnostic: written when the run failed: {f}")?;
    }
    writeln!(s, "time:       {} s", st.time)?;
    writeln!(s, "step:       {}", st.step)?;
    writeln!(s, "dt:         {} s", st.dt)?;
    writeln!(s, "scene:      {}", st.scene.origin)?;
    writeln!(s, "particles:  {} fluid, {} wall, {} solid", st.fluid.len(), st.walls.len(), st.solids.len())?;
    writeln!(s, "fluid volume per phase (outer, sum of h^3 alpha_k; inner, sum of h^3 beta_k):")?;
    let (outer, inner) = phase_volumes(st);
    for ((p, v), b) in st.scene.phases.iter().zip(outer).zip(inner) {
        writeln!(s, "  {:<16} {v:.6e} m^3 outer, {b:.6e} m^3 inner", p.name)?;
    }
    let r = &c.run;
    write!(s, "run:        frames written {}, next frame at {} s, ", r.frames_written, r.next_frame_time)?;
    match (r.stop_time, r.stop_step) {
        (_, Some(step)) => write!(s, "stops after step {step}")?,
        (Some(t), None) => write!(s, "stops at {t} s")?,
        (None, None) => write!(s, "no stop recorded")?,
    }
    if r.checkpoint_every.is_empty() {
        writeln!(s)?;
    } else {
        writeln!(s, ", checkpoint every {} (keep {})", r.checkpoint_every, r.keep)?;
    }
    let bad: Vec<&DatasetCheck> = checks.iter().filter(|c| !c.holds()).collect();
    if bad.is_empty() {
        writeln!(s, "checksums:  all {} datasets hold (XXH64)", checks.len())?;
    } else {
        writeln!(s, "checksums:  {} of {} datasets FAIL (XXH64):", bad.len(), checks.len())?;
        for b in bad {
            writeln!(s, "  {b}")?;
        }
    }
    Ok(())
}

/// Reads one checkpoint file: metadata through HDF5, particle arrays
/// through HDF5 or a memory map.
struct Reader<'a> {
    file: &'a File,
    /// Size of the file, bytes: no dataset can hold more.
    file_len: u64,
    map: Option<memmap2::Mmap>,
    /// Stop at the first checksum that fails (else collect them all).
    strict: bool,
    checks: Vec<DatasetCheck>,
}

impl<'a> Reader<'a> {
    fn new(path: &Path, file: &'a File, method: ReadMethod, strict: bool) -> Result<Self, IoError> {
        let map = match method {
            ReadMethod::Hdf5 => None,
            ReadMethod::Mmap => {
                let f = fs::File::open(path).map_err(|e| IoError::new(path, format!("cannot open: {e}")))?;
                // SAFETY: the map is read-only and lives while the file is
                // read; every slice taken from it is bounds-checked. A file
                // truncated by another process while it is being read can
                // still fault (SIGBUS), as with any memory map; porosph never
                // modifies a checkpoint once it has its final name.
                // MAP_POPULATE: map every page now, in one pass, rather than
                // fault them in one by one while copying.
                let map = unsafe { memmap2::MmapOptions::new().populate().map(&f) }
                    .map_err(|e| IoError::new(path, format!("cannot map: {e}")))?;
                Some(map)
            }
        };
        let file_len = fs::metadata(path).map_err(|e| IoError::new(path, format!("cannot read: {e}")))?.len();
        Ok(Self { file, file_len, map, strict, checks: Vec::new() })
    }

    fn read(&mut self) -> Result<Checkpoint, String> {
        let file = self.file;
        let root = file.attr_names().ctx("cannot read the root attributes (damaged file?)")?;
        if !root.iter().any(|n| n == "format") {
            return Err("not a porosph checkpoint (no format attribute)".to_string());
        }
        let format = attr_string(file, "format")?;
        if format != FORMAT {
            return Err(format!("not a porosph checkpoint (format attribute is {format:?})"));
        }
        let version: u32 = attr(file, "format_version")?;
        if version != FORMAT_VERSION {
            return Err(format!(
                "checkpoint format version {version}; this porosph ({}) reads version {FORMAT_VERSION}",
                env!("CARGO_PKG_VERSION")
            ));
        }
        let time: f64 = attr(file, "time")?;
        let step: u64 = attr(file, "step")?;
        let dt: f32 = attr(file, "dt")?;
        let nf = count(attr::<u64>(file, "fluid_particles")?)?;
        let nw = count(attr::<u64>(file, "wall_particles")?)?;
        let ns = count(attr::<u64>(file, "solid_particles")?)?;
        let failure = attr_string(file, "failure")?;

        let scene_ds = open_dataset(file, "scene")?;
        let origin = attr_string(&scene_ds, "origin")?;
        let stored: u64 = attr(&scene_ds, "xxh64")?;
        let got = scene_ds.dtype().and_then(|t| t.to_descriptor()).ctx("/scene: element type")?;
        if got != u8::type_descriptor() || scene_ds.ndim() != 1 {
            return Err(format!(
                "/scene has type {got} and shape {:?}, expected the scene text as bytes [n]",
                scene_ds.shape()
            ));
        }
        let bytes: Vec<u8> =
            if scene_ds.size() == 0 { Vec::new() } else { scene_ds.read_raw().ctx("cannot read /scene")? };
        let mut h = Xxh64::new(0);
        h.update(&bytes);
        self.check("/scene".to_string(), stored, h.finish())?;
        let text = String::from_utf8(bytes).map_err(|_| "/scene is not UTF-8 text".to_string())?;
        let scene = Scene::from_toml_str(&text, &origin).map_err(|e| {
            // Since mesh paths are stored absolute (`Scene::with_absolute_mesh_paths`),
            // only an older checkpoint's relative ones depend on where
            // porosph runs.
            let hint = if e.key.contains("mesh") && e.reason.contains("cannot read") {
                " (the checkpoint names the mesh file relative to the directory its run \
                     started in, or the file has moved: resume from that directory, or put the mesh back)"
            } else {
                ""
            };
            format!("the stored scene cannot be rebuilt: {e}{hint}")
        })?;

        let params = file.group("params").map_err(|_| "missing group /params".to_string())?;
        for (name, want) in param_values(&Params::from_scene(&scene)) {
            let got = match &want {
                Value::F32(_) => Value::F32(attr(&params, name)?),
                Value::U32(_) => Value::U32(attr(&params, name)?),
                Value::F32s(_) => Value::F32s(attr_vec(&params, name)?),
            };
            if !same_bits(&got, &want) {
                return Err(format!(
                    "/params@{name} is {got} but the stored scene gives {want}: \
                     the file was written by a porosph that derives parameters differently, \
                     or edited; resuming it would not continue the same run"
                ));
            }
        }

        let run = self.read_run()?;
        let phases = scene.phases.len();

        let mut fluid = FluidStore::default();
        let g = group(file, "fluid")?;
        self.check_count(&g, nf)?;
        let mut known = Vec::new();
        let mut result = Ok(());
        fluid.for_each_column_mut(|name, unit, c| {
            known.push(name);
            if result.is_ok() {
                result = match c {
                    // A file from before the fractions had low parts: the
                    // run it saved had none, so zeros continue it exactly.
                    ColumnMut::PerPhase(vs) if LOW_PARTS.contains(&name) && !g.link_exists(name) => {
                        *vs = vec![vec![0.0; nf]; phases];
                        Ok(())
                    }
                    c => self.read_column(&g, name, unit, c, nf, phases),
                };
            }
        });
        result.clone()?;
        check_no_unknown(&g, &known)?;

        let mut walls = WallStore::default();
        let g = group(file, "walls")?;
        self.check_count(&g, nw)?;
        known.clear();
        walls.for_each_column_mut(|name, unit, c| {
            known.push(name);
            if result.is_ok() {
                result = self.read_column(&g, name, unit, c, nw, phases);
            }
        });
        result.clone()?;
        check_no_unknown(&g, &known)?;

        let mut solids = SolidStore::default();
        let g = group(file, "solids")?;
        self.check_count(&g, ns)?;
        known.clear();
        solids.for_each_column_mut(|name, unit, c| {
            known.push(name);
            if result.is_ok() {
                result = match c {
                    // A file from before granular solids: all its solids
                    // were elastic, whose granular state is 0.
                    ColumnMut::F32(v) if GRANULAR_STATE.contains(&name) && !g.link_exists(name) => {
                        *v = vec![0.0; ns];
                        Ok(())
                    }
                    c => self.read_column(&g, name, unit, c, ns, phases),
                };
            }
        });
        result?;
        check_no_unknown(&g, &known)?;

        Ok(Checkpoint {
            format_version: version,
            state: SavedState { scene, fluid, walls, solids, time, step, dt },
            run,
            failure: (!failure.is_empty()).then_some(failure),
        })
    }

    fn read_run(&self) -> Result<RunInfo, String> {
        let g = group(self.file, "run")?;
        let optional = |name: &str| g.attr_names().map(|a| a.iter().any(|s| s == name));
        let has = |name: &str| optional(name).unwrap_or(false);
        Ok(RunInfo {
            frames_written: attr(&g, "frames_written")?,
            next_frame_time: attr(&g, "next_frame_time")?,
            frame_every: attr(&g, "frame_every")?,
            stop_time: if has("stop_time") { Some(attr(&g, "stop_time")?) } else { None },
            stop_step: if has("stop_step") { Some(attr(&g, "stop_step")?) } else { None },
            checkpoint_every: attr_string(&g, "checkpoint_every")?,
            keep: attr(&g, "keep")?,
            compress: has("compress") && attr::<u8>(&g, "compress")? != 0,
        })
    }

    /// Records a checksum; in strict mode a mismatch is the error.
    fn check(&mut self, name: String, stored: u64, computed: u64) -> Result<(), String> {
        let c = DatasetCheck { name, stored, computed };
        if self.strict && !c.holds() {
            return Err(c.to_string());
        }
        self.checks.push(c);
        Ok(())
    }

    fn check_count(&self, g: &Group, n: usize) -> Result<(), String> {
        let stored = count(attr::<u64>(g, "particles")?)?;
        if stored != n {
            return Err(format!("{}@particles is {stored} but the root attribute says {n}", g.name()));
        }
        Ok(())
    }

    /// Reads one registered column: dataset present, element type and shape
    /// as the registry says, unit as registered, data through its checksum.
    fn read_column(
        &mut self,
        g: &Group,
        name: &str,
        unit: &str,
        c: ColumnMut<'_>,
        n: usize,
        phases: usize,
    ) -> Result<(), String> {
        let what = format!("{}/{name}", g.name());
        let ds = open_dataset(g, name)?;
        let stored_unit = attr_string(&ds, "unit")?;
        if stored_unit != unit {
            return Err(format!("{what} has unit {stored_unit:?}, this porosph stores it in {unit:?}"));
        }
        let stored: u64 = attr(&ds, "xxh64")?;
        let (want_type, shape) = match &c {
            ColumnMut::F32(_) => (f32::type_descriptor(), vec![n]),
            ColumnMut::U32(_) => (u32::type_descriptor(), vec![n]),
            ColumnMut::PerPhase(_) => (f32::type_descriptor(), vec![phases, n]),
        };
        let got_type = ds.dtype().and_then(|t| t.to_descriptor()).ctx(format_args!("{what}: element type"))?;
        if got_type != want_type {
            return Err(format!("{what} has element type {got_type}, expected {want_type}"));
        }
        if ds.shape() != shape {
            return Err(format!("{what} has shape {:?}, expected {shape:?}", ds.shape()));
        }
        let bytes = shape.iter().try_fold(4u64, |b, &d| b.checked_mul(d as u64));
        if bytes.is_none_or(|b| b > self.file_len) {
            return Err(format!(
                "{what} claims more data ({shape:?} values) than the file holds ({} bytes): \
                 damaged or truncated",
                self.file_len
            ));
        }
        let mut h = Xxh64::new(0);
        match c {
            ColumnMut::F32(v) => *v = self.values(&ds, &what, &mut h, f32::from_le_bytes)?,
            ColumnMut::U32(v) => *v = self.values(&ds, &what, &mut h, u32::from_le_bytes)?,
            ColumnMut::PerPhase(vs) => {
                let flat: Vec<f32> = self.values(&ds, &what, &mut h, f32::from_le_bytes)?;
                *vs =
                    if n == 0 { vec![Vec::new(); phases] } else { flat.chunks_exact(n).map(<[f32]>::to_vec).collect() };
            }
        }
        self.check(what, stored, h.finish())
    }

    /// All values of a 4-byte dataset, hashed into `h` as they are read:
    /// from the memory map where the dataset is contiguous, else by HDF5.
    fn values<T: H5Type + Copy + Words>(
        &self,
        ds: &Dataset,
        what: &str,
        h: &mut Xxh64,
        from_le: fn([u8; 4]) -> T,
    ) -> Result<Vec<T>, String> {
        let len = ds.size();
        if let (Some(map), Some(offset), Layout::Contiguous) = (&self.map, ds.offset(), ds.layout()) {
            let bytes = usize::try_from(offset)
                .ok()
                .and_then(|start| Some(start..start.checked_add(len.checked_mul(4)?)?))
                .and_then(|range| map.get(range))
                .ok_or_else(|| {
                    format!("{what} ends past the end of the file ({} bytes): the file is truncated", map.len())
                })?;
            h.update(bytes);
            return Ok(bytes.chunks_exact(4).map(|b| from_le([b[0], b[1], b[2], b[3]])).collect());
        }
        let v: Vec<T> =
            if len == 0 { Vec::new() } else { ds.read_raw::<T>().ctx(format_args!("cannot read {what}"))? };
        T::hash(&v, h);
        Ok(v)
    }
}

/// Element types hashed as 32-bit little-endian words.
trait Words: Sized {
    fn hash(v: &[Self], h: &mut Xxh64);
}

impl Words for f32 {
    fn hash(v: &[Self], h: &mut Xxh64) {
        h.update_f32(v);
    }
}

impl Words for u32 {
    fn hash(v: &[Self], h: &mut Xxh64) {
        h.update_u32(v);
    }
}

/// Equal bit for bit (so 0.0 != -0.0 and NaN == the same NaN).
fn same_bits(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::F32(x), Value::F32(y)) => x.to_bits() == y.to_bits(),
        (Value::U32(x), Value::U32(y)) => x == y,
        (Value::F32s(x), Value::F32s(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
        }
        _ => false,
    }
}

fn count(n: u64) -> Result<usize, String> {
    usize::try_from(n).map_err(|_| format!("particle count {n} does not fit in memory"))
}

fn group(file: &File, name: &str) -> Result<Group, String> {
    file.group(name).map_err(|_| format!("missing group /{name}"))
}

fn open_dataset(g: &Group, name: &str) -> Result<Dataset, String> {
    let what = if g.name() == "/" { format!("/{name}") } else { format!("{}/{name}", g.name()) };
    if !g.link_exists(name) {
        return Err(format!("missing dataset {what}"));
    }
    g.dataset(name).map_err(|e| format!("cannot open dataset {what}: {e}"))
}

/// Datasets in `g` that the registry does not know hold state this porosph
/// would drop: an error, not a silent loss.
fn check_no_unknown(g: &Group, known: &[&str]) -> Result<(), String> {
    let names = g.member_names().ctx(format_args!("cannot list {}", g.name()))?;
    match names.iter().find(|n| !known.contains(&n.as_str())) {
        Some(extra) => Err(format!(
            "unknown dataset {}/{extra}: this porosph does not know that array \
             (written by a newer porosph?)",
            g.name()
        )),
        None => Ok(()),
    }
}

/// A scalar attribute of exactly type `T`.
fn attr<T: H5Type>(loc: &Location, name: &str) -> Result<T, String> {
    let what = attr_name(loc, name);
    let a = loc.attr(name).map_err(|_| format!("missing attribute {what}"))?;
    let got = a.dtype().and_then(|t| t.to_descriptor()).ctx(&what)?;
    let want = T::type_descriptor();
    if got != want {
        return Err(format!("{what} has type {got}, expected {want}"));
    }
    if a.size() != 1 {
        return Err(format!("{what} has shape {:?}, expected one value", a.shape()));
    }
    a.read_scalar::<T>().ctx(&what)
}

/// An array attribute of f32.
fn attr_vec(loc: &Location, name: &str) -> Result<Vec<f32>, String> {
    let what = attr_name(loc, name);
    let a = loc.attr(name).map_err(|_| format!("missing attribute {what}"))?;
    let got = a.dtype().and_then(|t| t.to_descriptor()).ctx(&what)?;
    if got != f32::type_descriptor() {
        return Err(format!("{what} has type {got}, expected float32"));
    }
    a.read_raw::<f32>().ctx(&what)
}

/// A fixed-length string attribute.
fn attr_string(loc: &Location, name: &str) -> Result<String, String> {
    let what = attr_name(loc, name);
    let a = loc.attr(name).map_err(|_| format!("missing attribute {what}"))?;
    let got = a.dtype().and_then(|t| t.to_descriptor()).ctx(&what)?;
    match got {
        TypeDescriptor::FixedUnicode(n) | TypeDescriptor::FixedAscii(n) if n <= STR_CAP && a.size() == 1 => {}
        _ => return Err(format!("{what} has type {got} and shape {:?}, expected one fixed-length string", a.shape())),
    }
    let v: FixedUnicode<STR_CAP> = a.read_scalar().ctx(&what)?;
    Ok(v.as_str().to_string())
}
