//! `stats.csv`: one row per step.
use super::IoError;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, BufWriter, ErrorKind, Seek, SeekFrom, Write};
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

    /// Continues the file of a run that resumes after step `after_step`
    /// (the step of its checkpoint).
    ///
    /// The header must be the one `columns` gives. Rows of steps after
    /// `after_step` (written by the run before it stopped, and about to be
    /// computed again) and a torn last line (a crash while writing it) are
    /// cut off, so the file keeps one row per step; new rows are appended.
    /// A missing or empty file is created with the header.
    pub fn append(path: &Path, columns: &[String], after_step: u64) -> Result<Self, IoError> {
        let header = columns.join(",");
        let keep = match File::open(path) {
            Ok(f) => {
                rows_to_keep(BufReader::new(f), &header, after_step).map_err(|reason| IoError::new(path, reason))?
            }
            Err(e) if e.kind() == ErrorKind::NotFound => None,
            Err(e) => return Err(IoError::new(path, format!("cannot read: {e}"))),
        };
        let Some(len) = keep else {
            return Self::create(path, columns);
        };
        let file = OpenOptions::new()
            .write(true)
            .open(path)
            .and_then(|mut f| {
                f.set_len(len)?;
                f.seek(SeekFrom::End(0))?;
                Ok(f)
            })
            .map_err(|e| IoError::new(path, format!("cannot append: {e}")))?;
        Ok(Self { path: path.to_path_buf(), out: BufWriter::new(file), columns: columns.len() })
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

/// The length in bytes of the part of a stats file to keep when resuming
/// after step `after_step`: the header and the complete rows of steps up to
/// it. `None` for an empty file (it gets a header).
fn rows_to_keep(mut r: impl BufRead, header: &str, after_step: u64) -> Result<Option<u64>, String> {
    let mut line = String::new();
    let read = |r: &mut dyn BufRead, line: &mut String| {
        line.clear();
        r.read_line(line).map_err(|e| format!("cannot read: {e}"))
    };
    let n = read(&mut r, &mut line)?;
    if n == 0 {
        return Ok(None);
    }
    if line.trim_end_matches(['\n', '\r']) != header {
        return Err(format!(
            "its header differs from the columns this porosph writes ({header}); \
             move it away to start a new one"
        ));
    }
    let mut keep = n as u64;
    for row in 2.. {
        let n = read(&mut r, &mut line)?;
        if n == 0 || !line.ends_with('\n') {
            break;
        }
        let first = line.split(',').next().unwrap_or("");
        let step: f64 =
            first.trim().parse().map_err(|_| format!("line {row} does not start with a step number: {first:?}"))?;
        if step > after_step as f64 {
            break;
        }
        keep += n as u64;
    }
    Ok(Some(keep))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_header_and_rows_up_to_the_step() {
        let text = "step,time\n1,0.1\n2,0.2\n3,0.3\n4,0.4";
        let keep = rows_to_keep(text.as_bytes(), "step,time", 2).expect("ok");
        assert_eq!(keep, Some("step,time\n1,0.1\n2,0.2\n".len() as u64));
        // A torn last line goes, complete rows stay.
        let keep = rows_to_keep(text.as_bytes(), "step,time", 10).expect("ok");
        assert_eq!(keep, Some("step,time\n1,0.1\n2,0.2\n3,0.3\n".len() as u64));
        assert_eq!(rows_to_keep(&b""[..], "step,time", 0), Ok(None));
        assert!(rows_to_keep(&b"a,b\n"[..], "step,time", 0).is_err());
        assert!(rows_to_keep(&b"step,time\nx,1\n"[..], "step,time", 0).is_err());
    }
}
