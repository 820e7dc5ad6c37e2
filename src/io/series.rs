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
//! Times are written with Rust's shortest round-trip `f64` formatting (`{:?}`:
//! `0.0`, `0.01`, `1e-7`, all valid JSON numbers), so reading the file back
//! gives the same bits.
use super::IoError;
use std::ffi::OsString;
use std::fmt::Write as _;
use std::fs;
use std::io::{ErrorKind, Write as _};
use std::path::{Path, PathBuf};

/// Keeps `frames.vtkhdf.series` up to date, rewriting it atomically after each frame.
pub struct SeriesWriter {
    path: PathBuf,
    entries: Vec<(String, f64)>,
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

    /// Writes the whole index to a temporary file next to it, syncs, and
    /// renames it over the index.
    fn write(&self) -> Result<(), IoError> {
        let path = &self.path;
        let name = path.file_name().ok_or_else(|| IoError::new(path, "not a file name"))?;
        let mut tmp_name = OsString::from(".");
        tmp_name.push(name);
        tmp_name.push(".tmp");
        let tmp = path.with_file_name(tmp_name);
        let text = render_series(&self.entries);
        let written = fs::File::create(&tmp)
            .and_then(|mut f| {
                f.write_all(text.as_bytes())?;
                f.sync_all()
            })
            .and_then(|()| fs::rename(&tmp, path));
        written.map_err(|e| {
            let _ = fs::remove_file(&tmp);
            IoError::new(path, format!("cannot write (via {}): {e}", tmp.display()))
        })
    }
}

/// The series file's text for `entries`.
fn render_series(entries: &[(String, f64)]) -> String {
    let mut s = String::from("{\n  \"file-series-version\" : \"1.0\",\n  \"files\" : [\n");
    for (i, (name, time)) in entries.iter().enumerate() {
        let sep = if i + 1 < entries.len() { "," } else { "" };
        // Writing into a String cannot fail.
        let _ = writeln!(s, "    {{ \"name\" : {}, \"time\" : {time:?} }}{sep}", json_string(name));
    }
    s.push_str("  ]\n}\n");
    s
}

/// `text` as a JSON string literal, quotes included.
fn json_string(text: &str) -> String {
    let mut s = String::with_capacity(text.len() + 2);
    s.push('"');
    for c in text.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            c if u32::from(c) < 0x20 => {
                let _ = write!(s, "\\u{:04x}", u32::from(c));
            }
            c => s.push(c),
        }
    }
    s.push('"');
    s
}

/// The `(name, time)` entries of a series file.
fn parse_series(text: &str) -> Result<Vec<(String, f64)>, String> {
    let mut parser = Parser { bytes: text.as_bytes(), pos: 0 };
    let root = parser.value(0)?;
    parser.skip_space();
    if parser.pos != parser.bytes.len() {
        return Err(parser.error("trailing text after the JSON value"));
    }
    let Json::Object(root) = root else {
        return Err("not a JSON object".to_string());
    };
    let files = match root.iter().find(|(k, _)| k == "files") {
        Some((_, Json::Array(files))) => files,
        Some(_) => return Err("\"files\" is not a list".to_string()),
        None => return Err("no \"files\" list".to_string()),
    };
    files
        .iter()
        .enumerate()
        .map(|(i, entry)| {
            let Json::Object(fields) = entry else {
                return Err(format!("files[{i}] is not an object"));
            };
            let name = match fields.iter().find(|(k, _)| k == "name") {
                Some((_, Json::String(name))) => name.clone(),
                _ => return Err(format!("files[{i}] has no string \"name\"")),
            };
            let time = match fields.iter().find(|(k, _)| k == "time") {
                Some((_, Json::Number(t))) if t.is_finite() => *t,
                _ => return Err(format!("files[{i}] has no numeric \"time\"")),
            };
            Ok((name, time))
        })
        .collect()
}

/// A parsed JSON value (only what a series file needs, but any JSON parses).
enum Json {
    Null,
    Bool,
    Number(f64),
    String(String),
    Array(Vec<Json>),
    Object(Vec<(String, Json)>),
}

/// Nesting deeper than this is rejected rather than risking the stack.
const MAX_DEPTH: usize = 64;

/// A small recursive-descent JSON parser over bytes; errors, never panics.
struct Parser<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Parser<'_> {
    fn error(&self, what: &str) -> String {
        format!("not a series file: {what} at byte {}", self.pos)
    }

    fn skip_space(&mut self) {
        while let Some(b' ' | b'\t' | b'\n' | b'\r') = self.bytes.get(self.pos) {
            self.pos += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.skip_space();
        self.bytes.get(self.pos).copied()
    }

    fn expect(&mut self, byte: u8) -> Result<(), String> {
        if self.peek() == Some(byte) {
            self.pos += 1;
            Ok(())
        } else {
            Err(self.error(&format!("expected '{}'", char::from(byte))))
        }
    }

    fn literal(&mut self, word: &str, value: Json) -> Result<Json, String> {
        if self.bytes[self.pos..].starts_with(word.as_bytes()) {
            self.pos += word.len();
            Ok(value)
        } else {
            Err(self.error("unexpected text"))
        }
    }

    fn value(&mut self, depth: usize) -> Result<Json, String> {
        if depth > MAX_DEPTH {
            return Err(self.error("nesting too deep"));
        }
        match self.peek() {
            Some(b'{') => self.object(depth),
            Some(b'[') => self.array(depth),
            Some(b'"') => self.string().map(Json::String),
            Some(b't') => self.literal("true", Json::Bool),
            Some(b'f') => self.literal("false", Json::Bool),
            Some(b'n') => self.literal("null", Json::Null),
            Some(b'-' | b'0'..=b'9') => self.number(),
            Some(_) => Err(self.error("unexpected character")),
            None => Err(self.error("unexpected end")),
        }
    }

    fn object(&mut self, depth: usize) -> Result<Json, String> {
        self.expect(b'{')?;
        let mut fields = Vec::new();
        if self.peek() == Some(b'}') {
            self.pos += 1;
            return Ok(Json::Object(fields));
        }
        loop {
            if self.peek() != Some(b'"') {
                return Err(self.error("expected a key"));
            }
            let key = self.string()?;
            self.expect(b':')?;
            fields.push((key, self.value(depth + 1)?));
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b'}') => {
                    self.pos += 1;
                    return Ok(Json::Object(fields));
                }
                _ => return Err(self.error("expected ',' or '}'")),
            }
        }
    }

    fn array(&mut self, depth: usize) -> Result<Json, String> {
        self.expect(b'[')?;
        let mut items = Vec::new();
        if self.peek() == Some(b']') {
            self.pos += 1;
            return Ok(Json::Array(items));
        }
        loop {
            items.push(self.value(depth + 1)?);
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b']') => {
                    self.pos += 1;
                    return Ok(Json::Array(items));
                }
                _ => return Err(self.error("expected ',' or ']'")),
            }
        }
    }

    fn number(&mut self) -> Result<Json, String> {
        let start = self.pos;
        while let Some(b'-' | b'+' | b'.' | b'e' | b'E' | b'0'..=b'9') = self.bytes.get(self.pos) {
            self.pos += 1;
        }
        // The bytes are ASCII, so this slice is valid UTF-8.
        let text = std::str::from_utf8(&self.bytes[start..self.pos]).unwrap_or("");
        text.parse::<f64>().map(Json::Number).map_err(|_| self.error("bad number"))
    }

    /// A string literal; the opening quote is at `pos`.
    fn string(&mut self) -> Result<String, String> {
        self.pos += 1;
        let mut out: Vec<u8> = Vec::new();
        loop {
            let Some(&b) = self.bytes.get(self.pos) else {
                return Err(self.error("unterminated string"));
            };
            self.pos += 1;
            match b {
                b'"' => break,
                b'\\' => {
                    let Some(&e) = self.bytes.get(self.pos) else {
                        return Err(self.error("unterminated string"));
                    };
                    self.pos += 1;
                    let c = match e {
                        b'"' => '"',
                        b'\\' => '\\',
                        b'/' => '/',
                        b'b' => '\u{8}',
                        b'f' => '\u{c}',
                        b'n' => '\n',
                        b'r' => '\r',
                        b't' => '\t',
                        b'u' => self.unicode_escape()?,
                        _ => return Err(self.error("bad escape")),
                    };
                    let mut buf = [0u8; 4];
                    out.extend_from_slice(c.encode_utf8(&mut buf).as_bytes());
                }
                b if b < 0x20 => return Err(self.error("control character in string")),
                b => out.push(b),
            }
        }
        String::from_utf8(out).map_err(|_| self.error("string is not UTF-8"))
    }

    /// The character of a `\uXXXX` escape (the `\u` already read), joining
    /// a surrogate pair.
    fn unicode_escape(&mut self) -> Result<char, String> {
        let hi = self.hex4()?;
        let code = if (0xd800..0xdc00).contains(&hi) {
            if !self.bytes[self.pos..].starts_with(b"\\u") {
                return Err(self.error("unpaired surrogate"));
            }
            self.pos += 2;
            let lo = self.hex4()?;
            if !(0xdc00..0xe000).contains(&lo) {
                return Err(self.error("unpaired surrogate"));
            }
            0x10000 + ((hi - 0xd800) << 10) + (lo - 0xdc00)
        } else {
            hi
        };
        char::from_u32(code).ok_or_else(|| self.error("bad \\u escape"))
    }

    fn hex4(&mut self) -> Result<u32, String> {
        let digits = self.bytes.get(self.pos..self.pos + 4).ok_or_else(|| self.error("short \\u escape"))?;
        let text = std::str::from_utf8(digits).map_err(|_| self.error("bad \\u escape"))?;
        let code = u32::from_str_radix(text, 16).map_err(|_| self.error("bad \\u escape"))?;
        self.pos += 4;
        Ok(code)
    }
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
