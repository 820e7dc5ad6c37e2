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

/// `stats.csv` read back: its columns by name, one value per row.
#[derive(Clone, Debug, PartialEq)]
pub struct StatsTable {
    /// Column names, from the header, in file order.
    pub columns: Vec<String>,
    /// `values[c][r]`: column `c` of data row `r`.
    pub values: Vec<Vec<f64>>,
    /// The last line did not end in a newline and was left out: porosph
    /// ends every row with one, so the run was writing it (or stopped while
    /// writing it) and its last value may be cut short.
    pub torn_last_line: bool,
}

impl StatsTable {
    /// Number of data rows.
    pub fn rows(&self) -> usize {
        self.values.first().map_or(0, Vec::len)
    }

    /// The values of column `name`, if there is one.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().position(|c| c == name).map(|i| self.values[i].as_slice())
    }
}

/// Reads a `stats.csv` (or any CSV of numbers with a header line). The
/// header is read generically: whatever columns it names. Errors name the
/// file, the line and why: a missing or empty file, a header without rows,
/// a row with the wrong number of values or a value that is not a number.
pub fn read_stats(path: &Path) -> Result<StatsTable, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::new(path, format!("cannot read: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let line = 1 + e.as_bytes()[..e.utf8_error().valid_up_to()].iter().filter(|&&b| b == b'\n').count();
        IoError::new(path, format!("line {line}: not UTF-8 text"))
    })?;
    parse_stats(&text).map_err(|reason| IoError::new(path, reason))
}

fn parse_stats(text: &str) -> Result<StatsTable, String> {
    let mut lines = text.split_inclusive('\n').enumerate().map(|(i, l)| (i + 1, l));
    let header = loop {
        match lines.next() {
            None => return Err("empty: no header line".into()),
            Some((_, l)) if l.trim().is_empty() => continue,
            Some((n, l)) => break (n, l.trim()),
        }
    };
    let columns: Vec<String> = header.1.split(',').map(|c| c.trim().to_string()).collect();
    for (i, c) in columns.iter().enumerate() {
        if c.is_empty() {
            return Err(format!("line {}: header column {} has no name", header.0, i + 1));
        }
        if columns[..i].contains(c) {
            return Err(format!("line {}: header names column `{c}` twice", header.0));
        }
    }
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); columns.len()];
    let mut torn_last_line = false;
    for (n, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        // Only the last line can lack its newline.
        if !line.ends_with('\n') {
            torn_last_line = true;
            break;
        }
        let row = parse_row(line.trim(), &columns).map_err(|reason| format!("line {n}: {reason}"))?;
        values.iter_mut().zip(row).for_each(|(col, v)| col.push(v));
    }
    if values[0].is_empty() {
        let why = if torn_last_line { " (the last line has no newline: being written?)" } else { "" };
        return Err(format!("no data rows after the header (line {}){why}", header.0));
    }
    Ok(StatsTable { columns, values, torn_last_line })
}

/// One data row: a number per column (`NaN` and `inf` are numbers).
fn parse_row(line: &str, columns: &[String]) -> Result<Vec<f64>, String> {
    let fields: Vec<&str> = line.split(',').collect();
    if fields.len() != columns.len() {
        let n = fields.len();
        return Err(format!(
            "{n} value{}, but the header names {} columns",
            if n == 1 { "" } else { "s" },
            columns.len()
        ));
    }
    fields
        .iter()
        .zip(columns)
        .map(|(f, c)| {
            let f = f.trim();
            f.parse().map_err(|_| format!("column `{c}`: {f:?} is not a number"))
        })
        .collect()
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

    #[test]
    fn reads_columns_by_header() {
        let t = parse_stats("step,time,ms_x\n1,0.5,NaN\n\n2,1e-3,inf\n").expect("ok");
        assert_eq!(t.columns, ["step", "time", "ms_x"]);
        assert_eq!(t.rows(), 2);
        assert_eq!(t.column("time"), Some(&[0.5, 1e-3][..]));
        assert!(t.column("ms_x").is_some_and(|c| c[0].is_nan() && c[1] == f64::INFINITY));
        assert_eq!(t.column("dt"), None);
        assert!(!t.torn_last_line);
    }

    #[test]
    fn torn_last_line_is_left_out_and_said() {
        // "0." parses, but may be the start of "0.51".
        for torn in ["2,0.", "2,", "2"] {
            let t = parse_stats(&format!("step,time\n1,0.5\n{torn}")).expect("ok");
            assert_eq!((t.rows(), t.torn_last_line), (1, true), "{torn:?}");
        }
        // Blank last line: nothing torn.
        let t = parse_stats("step,time\n1,0.5\n  ").expect("ok");
        assert_eq!((t.rows(), t.torn_last_line), (1, false));
    }

    #[test]
    fn bad_tables_name_the_line_and_why() {
        for (text, want) in [
            ("", "empty"),
            ("\n\n", "empty"),
            ("step,time\n", "no data rows"),
            ("step,time\n1,0.5", "no data rows"),
            ("step,,time\n1,2,3\n", "line 1: header column 2 has no name"),
            ("step,time,step\n1,2,3\n", "line 1: header names column `step` twice"),
            ("step,time\n1,2\n1,2,3\n", "line 3: 3 values, but the header names 2 columns"),
            ("step,time\n1,2\n2,x\n3,4\n", "line 3: column `time`: \"x\" is not a number"),
            ("step,time\n1,2\n2,\n", "line 3: column `time`: \"\" is not a number"),
        ] {
            let e = parse_stats(text).expect_err(text);
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
