//! `frames.vtkhdf.series`: the JSON index of frame files and times. (placeholder)
use super::IoError;
use std::path::{Path, PathBuf};

/// Keeps `frames.vtkhdf.series` up to date, rewriting it atomically after each frame.
pub struct SeriesWriter {
    path: PathBuf,
    entries: Vec<(String, f64)>,
}

impl SeriesWriter {
    /// A series index at `path` (not written until the first [`SeriesWriter::add`]).
    pub fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            entries: Vec::new(),
        }
    }

    /// Adds a frame file name (relative to the series file) at simulated time `time`.
    pub fn add(&mut self, _file_name: &str, _time: f64) -> Result<(), IoError> {
        let _ = (&self.path, &self.entries);
        unimplemented!("series")
    }
}
