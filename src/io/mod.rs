//! Output and input files: frames for viewers (VTKHDF), the frame series
//! index, per-step statistics, checkpoints (complete state, HDF5), and
//! reading them back for `porosph inspect` and `porosph resume`.

pub mod atomic;
pub mod checkpoint;
pub mod h5;
mod series;
mod stats;
mod vtkhdf;
pub mod xxh64;

pub use series::SeriesWriter;
pub use stats::{read_stats, StatsTable, StatsWriter};
pub use vtkhdf::{inspect_frame, read_frame, write_frame, write_frame_as, FrameLayout, SharedRows, DEFLATE_LEVEL};

use std::fmt;
use std::path::{Path, PathBuf};

/// One frame: every particle (fluid, solid and wall) as one point set.
/// Owned, because frames are rare and built outside the step's hot path.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Simulated time, s.
    pub time: f64,
    /// Step number.
    pub step: u64,
    /// Positions, m, one `[x, y, z]` per point.
    pub points: Vec<[f32; 3]>,
    /// Point arrays (`PointData/<name>` in the file), in the order written.
    pub arrays: Vec<PointArray>,
}

impl Frame {
    /// The points `rows` with their values of every array, at the same
    /// time and step.
    pub fn rows(&self, rows: std::ops::Range<usize>) -> Frame {
        let arrays = self
            .arrays
            .iter()
            .map(|a| {
                let (lo, hi) = (rows.start * a.components, rows.end * a.components);
                let data = match &a.data {
                    ArrayData::F32(v) => ArrayData::F32(v[lo..hi].to_vec()),
                    ArrayData::U32(v) => ArrayData::U32(v[lo..hi].to_vec()),
                    ArrayData::U8(v) => ArrayData::U8(v[lo..hi].to_vec()),
                };
                PointArray { name: a.name.clone(), unit: a.unit.clone(), components: a.components, data }
            })
            .collect();
        Frame { time: self.time, step: self.step, points: self.points[rows].to_vec(), arrays }
    }
}

/// A named per-point array; `data.len() == points * components`, point-major
/// (the components of one point are adjacent), as VTKHDF stores them.
#[derive(Clone, Debug, PartialEq)]
pub struct PointArray {
    pub name: String,
    /// Unit, written as the dataset attribute `unit` ("" if dimensionless).
    pub unit: String,
    pub components: usize,
    pub data: ArrayData,
}

/// The element type of a [`PointArray`].
#[derive(Clone, Debug, PartialEq)]
pub enum ArrayData {
    F32(Vec<f32>),
    U32(Vec<u32>),
    U8(Vec<u8>),
}

/// A file problem, naming the file.
#[derive(Debug)]
pub struct IoError {
    pub path: PathBuf,
    pub reason: String,
}

impl IoError {
    pub fn new(path: &Path, reason: impl fmt::Display) -> Self {
        Self { path: path.to_path_buf(), reason: reason.to_string() }
    }
}

impl fmt::Display for IoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.reason)
    }
}

impl std::error::Error for IoError {}
