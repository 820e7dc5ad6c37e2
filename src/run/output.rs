//! A run owns its output directory: a new run writes only into a missing or
//! empty directory, so the frames, checkpoints and statistics there are all
//! its own (`porosph render --movie` and ParaView's file grouping take every
//! `frame_*` file they find). `--overwrite` first removes the files of an
//! earlier porosph run, and only those: a directory holding anything else
//! (a name or file type porosph does not write) is never cleared.
//!
//! What porosph writes into `OUT`: `scene.toml`, `stats.csv`, `plots.png`;
//! `frames/` (`frame_<n>.vtkhdf`, `frame_<n>_failed.vtkhdf`,
//! `walls.vtkhdf`, `frames.vtkhdf.series`, and `frame_<n>.png` pictures that `porosph
//! render` puts beside a frame); `checkpoints/` (`ckpt_<step>.h5`,
//! `ckpt_<step>_failed.h5`); `render/` (`frame_<n>.png`); and the
//! `.<name>.tmp` files of an atomic write that was cut short.

use crate::io::IoError;
use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

/// What an existing output directory holds.
#[derive(Clone, Debug, Default)]
pub struct Survey {
    /// The directory.
    pub dir: PathBuf,
    /// Frame files (`frames/*.vtkhdf`, failed ones included).
    pub frames: usize,
    /// Whether `frames/frames.vtkhdf.series` is there.
    pub series: bool,
    /// Whether `frames/walls.vtkhdf` (the run's static walls) is there.
    pub walls: bool,
    /// Checkpoints (`checkpoints/*.h5`, diagnostic ones included).
    pub checkpoints: usize,
    /// Pictures (`render/*.png`, `frames/*.png`).
    pub pictures: usize,
    /// Temporary files of writes cut short.
    pub temporaries: usize,
    /// Single files at the top: `scene.toml`, `stats.csv`, `plots.png`.
    pub named: Vec<&'static str>,
    /// Every file porosph wrote, to remove (then their folders).
    files: Vec<PathBuf>,
    /// The folders porosph made (`frames`, `checkpoints`, `render`).
    folders: Vec<PathBuf>,
    /// Entries porosph did not write, relative to `dir` (a folder with a `/`).
    pub foreign: Vec<String>,
}

/// Why an output directory cannot be used.
#[derive(Debug)]
pub struct OutputError(pub String);

impl fmt::Display for OutputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for OutputError {}

/// `<prefix><digits>.<ext>` or `<prefix><digits>_failed.<ext>`.
fn numbered(name: &str, prefix: &str, ext: &str) -> bool {
    let Some(stem) = name.strip_prefix(prefix).and_then(|r| r.strip_suffix(ext)).and_then(|r| r.strip_suffix('.'))
    else {
        return false;
    };
    let digits = stem.strip_suffix("_failed").unwrap_or(stem);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// A name porosph writes, or the temporary name of one (`.<name>.tmp`);
/// `Some(true)` for a temporary.
fn porosph_name(name: &str, is_ours: impl Fn(&str) -> bool) -> Option<bool> {
    if is_ours(name) {
        return Some(false);
    }
    let inner = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    is_ours(inner).then_some(true)
}

/// Lists `dir`, recognising porosph's files. `Ok(None)`: missing or empty.
pub fn survey(dir: &Path) -> Result<Option<Survey>, OutputError> {
    let meta = match fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        // A folder on the way is a file: name it.
        Err(e) if e.kind() == std::io::ErrorKind::NotADirectory => {
            let file = dir.ancestors().skip(1).find(|a| fs::metadata(a).is_ok_and(|m| !m.is_dir()));
            return Err(OutputError(match file {
                Some(f) => {
                    format!("--out {}: {} is a file, not a directory; choose another --out", dir.display(), f.display())
                }
                None => format!("--out {}: cannot read: {e}", dir.display()),
            }));
        }
        Err(e) => return Err(OutputError(format!("{}: cannot read: {e}", dir.display()))),
    };
    if !fs::metadata(dir).map(|m| m.is_dir()).unwrap_or(meta.is_dir()) {
        return Err(OutputError(format!(
            "--out {} names a file, not a directory (a run writes frames/, checkpoints/ and \
             stats.csv into a directory); choose another --out",
            dir.display()
        )));
    }
    let list = |d: &Path| -> Result<Vec<(String, fs::FileType)>, OutputError> {
        let rd = fs::read_dir(d).map_err(|e| OutputError(format!("{}: cannot list: {e}", d.display())))?;
        let mut v = Vec::new();
        for e in rd {
            let e = e.map_err(|e| OutputError(format!("{}: cannot list: {e}", d.display())))?;
            let t = e.file_type().map_err(|err| OutputError(format!("{}: {err}", e.path().display())))?;
            v.push((e.file_name().to_string_lossy().into_owned(), t));
        }
        v.sort_by(|a, b| a.0.cmp(&b.0));
        Ok(v)
    };
    let top = list(dir)?;
    if top.is_empty() {
        return Ok(None);
    }
    let mut s = Survey { dir: dir.to_path_buf(), ..Survey::default() };
    for (name, t) in &top {
        let path = dir.join(name);
        let folder = |s: &mut Survey, kind: fn(&str) -> Option<(Category, bool)>| -> Result<(), OutputError> {
            for (inner, it) in list(&path)? {
                match kind(&inner) {
                    Some((cat, tmp)) if it.is_file() => {
                        if tmp {
                            s.temporaries += 1;
                        } else {
                            match cat {
                                Category::Frame => s.frames += 1,
                                Category::Series => s.series = true,
                                Category::Walls => s.walls = true,
                                Category::Checkpoint => s.checkpoints += 1,
                                Category::Picture => s.pictures += 1,
                            }
                        }
                        s.files.push(path.join(&inner));
                    }
                    _ => s.foreign.push(format!("{name}/{inner}{}", if it.is_dir() { "/" } else { "" })),
                }
            }
            s.folders.push(path.clone());
            Ok(())
        };
        match name.as_str() {
            "frames" if t.is_dir() => folder(&mut s, frames_kind)?,
            "checkpoints" if t.is_dir() => folder(&mut s, checkpoints_kind)?,
            "render" if t.is_dir() => folder(&mut s, render_kind)?,
            _ if t.is_file() => match porosph_name(name, |n| TOP_FILES.contains(&n)) {
                Some(true) => {
                    s.temporaries += 1;
                    s.files.push(path);
                }
                Some(false) => {
                    s.named.extend(TOP_FILES.iter().find(|&&n| n == name));
                    s.files.push(path);
                }
                None => s.foreign.push(name.clone()),
            },
            _ => s.foreign.push(format!("{name}{}", if t.is_dir() { "/" } else { "" })),
        }
    }
    // A scene file alone is the user's own scene, not a run.
    if s.named == ["scene.toml"] && s.folders.is_empty() && s.temporaries == 0 {
        s.named.clear();
        s.files.clear();
        s.foreign.push("scene.toml".to_string());
    }
    Ok(Some(s))
}

/// Single files porosph writes at the top of `OUT`.
const TOP_FILES: [&str; 3] = ["scene.toml", "stats.csv", "plots.png"];

#[derive(Clone, Copy)]
enum Category {
    Frame,
    Series,
    Walls,
    Checkpoint,
    Picture,
}

fn frames_kind(name: &str) -> Option<(Category, bool)> {
    let cat = |n: &str| {
        if n == "frames.vtkhdf.series" {
            Some(Category::Series)
        } else if n == super::WALLS_FILE {
            Some(Category::Walls)
        } else if numbered(n, "frame_", "vtkhdf") {
            Some(Category::Frame)
        } else if numbered(n, "frame_", "png") {
            Some(Category::Picture)
        } else {
            None
        }
    };
    let tmp = porosph_name(name, |n| cat(n).is_some())?;
    let inner = if tmp { &name[1..name.len() - 4] } else { name };
    Some((cat(inner)?, tmp))
}

fn checkpoints_kind(name: &str) -> Option<(Category, bool)> {
    porosph_name(name, |n| numbered(n, "ckpt_", "h5")).map(|tmp| (Category::Checkpoint, tmp))
}

fn render_kind(name: &str) -> Option<(Category, bool)> {
    porosph_name(name, |n| numbered(n, "frame_", "png")).map(|tmp| (Category::Picture, tmp))
}

fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

impl Survey {
    /// Whether everything in the directory is porosph's.
    pub fn is_porosph_run(&self) -> bool {
        self.foreign.is_empty()
    }

    /// Whether porosph's files are there at all.
    pub fn has_porosph_files(&self) -> bool {
        !self.files.is_empty()
    }

    /// porosph's files in words: "31 frames, the frame series index, 2
    /// checkpoints, stats.csv, scene.toml".
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if self.frames > 0 {
            parts.push(plural(self.frames, "frame", "frames"));
        }
        if self.series {
            parts.push("the frame series index".to_string());
        }
        if self.walls {
            parts.push("the walls file".to_string());
        }
        if self.checkpoints > 0 {
            parts.push(plural(self.checkpoints, "checkpoint", "checkpoints"));
        }
        if self.pictures > 0 {
            parts.push(plural(self.pictures, "rendered picture", "rendered pictures"));
        }
        parts.extend(self.named.iter().map(|n| n.to_string()));
        if self.temporaries > 0 {
            parts.push(plural(self.temporaries, "temporary file", "temporary files"));
        }
        if parts.is_empty() {
            parts.push("empty frames/, checkpoints/ or render/ folders".to_string());
        }
        parts.join(", ")
    }

    /// The first few entries porosph did not write.
    pub fn describe_foreign(&self) -> String {
        const SHOWN: usize = 5;
        let mut s = self.foreign.iter().take(SHOWN).cloned().collect::<Vec<_>>().join(", ");
        if self.foreign.len() > SHOWN {
            s.push_str(&format!(" and {} more", self.foreign.len() - SHOWN));
        }
        s
    }

    /// Removes porosph's files, then its (now empty) folders; never touches
    /// anything else. Refused if the directory holds anything foreign.
    pub fn remove(&self) -> Result<(), IoError> {
        if !self.is_porosph_run() {
            return Err(IoError::new(
                &self.dir,
                format!("holds files porosph did not write: {}", self.describe_foreign()),
            ));
        }
        for f in &self.files {
            fs::remove_file(f).map_err(|e| IoError::new(f, format!("cannot remove: {e}")))?;
        }
        for d in &self.folders {
            fs::remove_dir(d).map_err(|e| IoError::new(d, format!("cannot remove: {e}")))?;
        }
        Ok(())
    }
}

/// The error for a new run into `s.dir` that is not empty: what is there,
/// and what to do. `newest` is the newest checkpoint there, if any.
fn refusal(s: &Survey, overwrite: bool, newest: Option<&Path>) -> OutputError {
    let d = s.dir.display();
    if !s.is_porosph_run() {
        let mut m = format!("--out {d} is not empty: it holds {}, which porosph did not write", s.describe_foreign());
        if s.has_porosph_files() {
            m.push_str(&format!(", besides an earlier porosph run's {}", s.describe()));
        }
        m.push_str("; choose another --out (an empty or new directory)");
        if overwrite {
            m.push_str(": --overwrite removes only the files of an earlier porosph run, never other files");
        }
        return OutputError(m);
    }
    let mut m = format!(
        "--out {d} holds an earlier porosph run ({}); a run does not mix its output with another's: \
         pass --overwrite to remove those files first, or choose another --out",
        s.describe()
    );
    if let Some(c) = newest {
        m.push_str(&format!(", or continue that run with `porosph resume {}`", shell_quote(c)));
    }
    OutputError(m)
}

/// What a run may do with its output directory.
#[derive(Debug)]
pub enum Claim {
    /// Missing or empty: the run creates it and writes.
    Fresh,
    /// An earlier porosph run is there; `--overwrite` removes it before
    /// the run starts ([`Survey::remove`]).
    Replace(Survey),
}

/// Checks that a new run may write into `out`: missing or empty; or, with
/// `overwrite`, holding only an earlier porosph run's files.
pub fn claim(out: &Path, overwrite: bool) -> Result<Claim, OutputError> {
    let Some(s) = survey(out)? else {
        return Ok(Claim::Fresh);
    };
    if overwrite && s.is_porosph_run() {
        return Ok(Claim::Replace(s));
    }
    let newest = super::newest_checkpoint(&out.join("checkpoints"));
    Err(refusal(&s, overwrite, newest.as_deref()))
}

/// `path` for a POSIX shell: as is when it holds only safe characters,
/// else in single quotes.
pub fn shell_quote(path: &Path) -> String {
    let s = path.to_string_lossy();
    let safe = |c: char| c.is_ascii_alphanumeric() || "_-./:+@%,=".contains(c);
    if !s.is_empty() && s.chars().all(safe) {
        s.into_owned()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recognises_porosph_names() {
        assert!(numbered("frame_00012.vtkhdf", "frame_", "vtkhdf"));
        assert!(numbered("frame_00012_failed.vtkhdf", "frame_", "vtkhdf"));
        assert!(numbered("ckpt_00000016.h5", "ckpt_", "h5"));
        for bad in ["frame_.vtkhdf", "frame_12a.vtkhdf", "frame_12.vtkhdf.bak", "xframe_1.vtkhdf", "frame_1vtkhdf"] {
            assert!(!numbered(bad, "frame_", "vtkhdf"), "{bad}");
        }
        assert!(matches!(frames_kind(".frame_00001.vtkhdf.tmp"), Some((Category::Frame, true))));
        assert!(matches!(frames_kind(".frames.vtkhdf.series.tmp"), Some((Category::Series, true))));
        assert!(matches!(frames_kind("frame_00001.png"), Some((Category::Picture, false))));
        assert!(matches!(frames_kind("walls.vtkhdf"), Some((Category::Walls, false))));
        assert!(matches!(frames_kind(".walls.vtkhdf.tmp"), Some((Category::Walls, true))));
        assert!(frames_kind("notes.txt").is_none());
        assert!(matches!(checkpoints_kind(".ckpt_00000001.h5.tmp"), Some((Category::Checkpoint, true))));
        assert!(checkpoints_kind("ckpt_1.h5.old").is_none());
    }

    #[test]
    fn quotes_for_the_shell() {
        assert_eq!(shell_quote(Path::new("out/checkpoints/ckpt_00000012.h5")), "out/checkpoints/ckpt_00000012.h5");
        assert_eq!(shell_quote(Path::new("my run/c.h5")), "'my run/c.h5'");
        assert_eq!(shell_quote(Path::new("it's/c.h5")), r"'it'\''s/c.h5'");
    }
}
