//! `stats.csv`: one row per step.
use super::IoError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes `stats.csv`. Each row is flushed, so a crash loses at most the row
/// being written.
pub struct StatsWriter {
    path: PathBuf,
    out: BufWriter<File>,
    columns: usize,
}

impl StatsWriter {
    /// Creates (truncates) the file and writes the header.
    pub fn create(path: &Path, columns: &[String]) -> Result<Self, IoError> {
        let file = File::create(path).map_err(|e| IoError::new(path, e))?;
        let mut out = BufWriter::new(file);
        writeln!(out, "{}", columns.join(",")).map_err(|e| IoError::new(path, e))?;
        out.flush().map_err(|e| IoError::new(path, e))?;
        Ok(Self { path: path.to_path_buf(), out, columns: columns.len() })
    }

    /// Writes one row; `values.len()` must equal the number of columns.
    pub fn row(&mut self, values: &[f64]) -> Result<(), IoError> {
        debug_assert_eq!(values.len(), self.columns);
        let mut first = true;
        for v in values {
            if !first {
                self.out.write_all(b",").map_err(|e| IoError::new(&self.path, e))?;
            }
            first = false;
            write!(self.out, "{v}").map_err(|e| IoError::new(&self.path, e))?;
        }
        self.out.write_all(b"\n").map_err(|e| IoError::new(&self.path, e))?;
        self.out.flush().map_err(|e| IoError::new(&self.path, e))
    }
}
