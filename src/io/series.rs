//! `frames.vtkhdf.series`: the JSON index of frame files and times that
//! ParaView opens as one time series:
//!
//! ```text
//! {
//!   "file-series-version" : "1.0",
//!   "files" : [
//!     { "name" : "frame_00000.vtkhdf", "time" : 0.0 },
//!     { "name" : "frame_00001.vtkhdf", "time" : 0.01 }
//!   ]
//! }
//! ```
//!
//! Names and times are encoded and read with serde_json: a time is written
//! as the shortest decimal that reads back as the same `f64`, and read with
//! the `float_roundtrip` parser, so it survives a write and a read bit for
//! bit.
use super::IoError;
use serde::Deserialize;
use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// Keeps `frames.vtkhdf.series` up to date, rewriting it atomically after each frame.
pub struct SeriesWriter {
    path: PathBuf,
    entries: Vec<(String, f64)>,
}

/// The file as serde reads it; other keys ParaView may write are ignored.
#[derive(Deserialize)]
struct SeriesFile {
    files: Vec<SeriesEntry>,
}

#[derive(Deserialize)]
struct SeriesEntry {
    name: String,
    time: f64,
}

impl SeriesWriter {
    /// A series index at `path` (not written until the first [`SeriesWriter::add`]).
    pub fn new(path: &Path) -> Self {
        Self { path: path.to_path_buf(), entries: Vec::new() }
    }

    /// The series index at `path` with the entries it already lists, for a
    /// run that resumes; a missing file gives an empty series. A file that is
    /// not a series index (not JSON, no `files` list, an entry without a
    /// string `name` or a finite numeric `time`) is an error.
    pub fn open_existing(path: &Path) -> Result<Self, IoError> {
        let text = match fs::read_to_string(path) {
            Ok(text) => text,
            Err(e) if e.kind() == ErrorKind::NotFound => return Ok(Self::new(path)),
            Err(e) => return Err(IoError::new(path, format!("cannot read: {e}"))),
        };
        let entries = parse_series(&text).map_err(|reason| IoError::new(path, reason))?;
        Ok(Self { path: path.to_path_buf(), entries })
    }

    /// The listed frames, `(file name, time)`, in file order.
    pub fn entries(&self) -> &[(String, f64)] {
        &self.entries
    }

    /// Adds a frame file name (relative to the series file) at simulated time
    /// `time` and rewrites the index (temporary file, then rename). A name
    /// already listed (a frame rewritten after a resume) keeps its place and
    /// takes the new time. `time` must be finite: JSON has no NaN.
    pub fn add(&mut self, file_name: &str, time: f64) -> Result<(), IoError> {
        if !time.is_finite() {
            return Err(IoError::new(&self.path, format!("time {time} of {file_name:?} is not finite")));
        }
        match self.entries.iter_mut().find(|(name, _)| name == file_name) {
            Some(entry) => entry.1 = time,
            None => self.entries.push((file_name.to_string(), time)),
        }
        self.write()
    }

    /// Keeps only the entries whose names pass `keep` and rewrites the
    /// index if any went; returns how many went.
    pub fn retain(&mut self, mut keep: impl FnMut(&str) -> bool) -> Result<usize, IoError> {
        let before = self.entries.len();
        self.entries.retain(|(name, _)| keep(name));
        let gone = before - self.entries.len();
        if gone > 0 {
            self.write()?;
        }
        Ok(gone)
    }

    /// Writes the whole index to a temporary file next to it, syncs, and
    /// renames it over the index.
    pub fn write(&self) -> Result<(), IoError> {
        let text = render_series(&self.entries);
        super::atomic::write_bytes(&self.path, text.as_bytes())
    }
}

/// The series file's text for `entries`: ParaView's layout, one entry a
/// line, with names and times encoded by serde_json.
fn render_series(entries: &[(String, f64)]) -> String {
    let mut s = String::from("{\n  \"file-series-version\" : \"1.0\",\n  \"files\" : [\n");
    for (i, (name, time)) in entries.iter().enumerate() {
        let sep = if i + 1 < entries.len() { "," } else { "" };
        // A string, and a finite f64 (`add` checks), always serialize.
        let name = serde_json::to_string(name).unwrap_or_default();
        let time = serde_json::to_string(time).unwrap_or_default();
        s.push_str(&format!("    {{ \"name\" : {name}, \"time\" : {time} }}{sep}\n"));
    }
    s.push_str("  ]\n}\n");
    s
}

/// The `(name, time)` entries of a series file.
fn parse_series(text: &str) -> Result<Vec<(String, f64)>, String> {
    // JSON numbers are finite: serde_json rejects 1e999 as out of range.
    let file: SeriesFile = serde_json::from_str(text).map_err(|e| format!("not a series file: {e}"))?;
    Ok(file.files.into_iter().map(|e| (e.name, e.time)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn render_then_parse_round_trips_names_and_times() {
        let entries = vec![
            ("frame_00000.vtkhdf".to_string(), 0.0),
            ("we\"ird\\ na\nme\u{1}é.vtkhdf".to_string(), 0.1),
            ("f.vtkhdf".to_string(), 1.0 / 3.0),
            ("g.vtkhdf".to_string(), 1e-300),
        ];
        let parsed = parse_series(&render_series(&entries)).expect("parses");
        assert_eq!(parsed.len(), entries.len());
        for (a, b) in parsed.iter().zip(&entries) {
            assert_eq!(a.0, b.0);
            assert_eq!(a.1.to_bits(), b.1.to_bits());
        }
    }

    /// Finite doubles from random bit patterns (every exponent, subnormals
    /// included) and the classic hard cases of decimal conversion read back
    /// bit for bit: the parser must be the exact one (`float_roundtrip`).
    #[test]
    fn times_read_back_bit_exact() {
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut times = vec![5e-324, f64::MIN_POSITIVE, 2.225_073_858_507_201e-308, f64::MAX, 9_007_199_254_740_993.0];
        times.extend([0.1 + 0.2, 1.0 / 3.0, 2.0f64.powi(-1074), 123_456.789e-200, -0.0]);
        while times.len() < 20_000 {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            let t = f64::from_bits(state);
            if t.is_finite() {
                times.push(t);
            }
        }
        let entries: Vec<(String, f64)> = times.iter().map(|&t| ("f.vtkhdf".to_string(), t)).collect();
        let parsed = parse_series(&render_series(&entries)).expect("parses");
        for ((_, a), (_, b)) in parsed.iter().zip(&entries) {
            assert_eq!(a.to_bits(), b.to_bits(), "{b:e} read back as {a:e}");
        }
        assert_eq!(parsed.len(), entries.len());
    }

    #[test]
    fn junk_is_an_error_not_a_panic() {
        let deep = "[".repeat(100_000);
        let junk = [
            "",
            "{",
            "[]",
            "{\"files\": 3}",
            "{\"files\": [1]}",
            "{\"files\": [{\"name\": 1, \"time\": 0}]}",
            "{\"files\": [{\"name\": \"a\"}]}",
            "{\"files\": [{\"name\": \"a\", \"time\": 1e999}]}",
            "{\"files\": []} x",
            "{\"files\": [{\"name\": \"\\ud800\", \"time\": 0}]}",
            "{\"files\": [{\"name\": \"\\u12",
            "{\"files\": [{\"name\": \"abc",
            "tru",
            "-",
            deep.as_str(),
        ];
        for text in junk {
            assert!(parse_series(text).is_err(), "accepted {text:?}");
        }
    }

    #[test]
    fn parses_paraview_style_files() {
        let text = r#"{"file-series-version":"1.0","files":[{"name":"a\u00e9\ud83d\ude00.vtkhdf","time":2.5E-3,"extra":[null,true,false,{}]}]}"#;
        let parsed = parse_series(text).expect("parses");
        assert_eq!(parsed, vec![("aé😀.vtkhdf".to_string(), 0.0025)]);
    }
}
