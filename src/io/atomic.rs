//! Writing a file so that a crash never leaves it torn: frames, checkpoints,
//! the series index and PNG images all go through [`write_with`].
//!
//! The content is written to `.<name>.tmp` in the same directory (so the
//! rename cannot cross file systems), synced to disk, renamed over the
//! target, and the directory is synced so that the rename itself survives
//! a power cut. A crash at any moment leaves either the old file or the new
//! one at the target; on error the temporary file is removed and nothing
//! else is touched.

use super::IoError;
use std::ffi::OsString;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// `.<file name>.tmp` next to `path`: the name a file has while it is being
/// written.
pub fn temp_path(path: &Path) -> Result<PathBuf, IoError> {
    let name = path.file_name().ok_or_else(|| IoError::new(path, "not a file name"))?;
    let mut tmp = OsString::from(".");
    tmp.push(name);
    tmp.push(".tmp");
    Ok(path.with_file_name(tmp))
}

/// Writes `path` atomically: `write` creates and fills the file at the
/// temporary path it is given (and closes it); the file is then synced,
/// renamed over `path`, and the directory synced. `write`'s error, or a
/// failing sync or rename, is returned naming `path`, and the temporary
/// file is removed.
pub fn write_with(path: &Path, write: impl FnOnce(&Path) -> Result<(), String>) -> Result<(), IoError> {
    let tmp = temp_path(path)?;
    let written = write(&tmp)
        .and_then(|()| sync_file(&tmp))
        .and_then(|()| fs::rename(&tmp, path).map_err(|e| format!("cannot rename {} to it: {e}", tmp.display())));
    if let Err(reason) = written {
        // Best effort: the temporary file may not exist (creation failed).
        let _ = fs::remove_file(&tmp);
        return Err(IoError::new(path, reason));
    }
    sync_dir(path);
    Ok(())
}

/// Writes `bytes` to `path` atomically (see [`write_with`]).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    write_with(path, |tmp| {
        fs::File::create(tmp)
            .and_then(|mut f| f.write_all(bytes))
            .map_err(|e| format!("cannot write {}: {e}", tmp.display()))
    })
}

/// Forces the closed file's data to disk before the rename makes it visible.
fn sync_file(tmp: &Path) -> Result<(), String> {
    fs::File::open(tmp).and_then(|f| f.sync_all()).map_err(|e| format!("cannot sync {}: {e}", tmp.display()))
}

/// Makes a rename in the directory of `path` durable; best effort (the file
/// is complete either way, and some file systems cannot sync a directory).
fn sync_dir(path: &Path) {
    if let Some(dir) = path.parent() {
        let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
        let _ = fs::File::open(dir).and_then(|d| d.sync_all());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("porosph-atomic-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    #[test]
    fn replaces_the_file_and_leaves_no_temporary() {
        let dir = scratch("replace");
        let path = dir.join("a.txt");
        write_bytes(&path, b"one").expect("first write");
        write_bytes(&path, b"two").expect("second write");
        assert_eq!(fs::read(&path).expect("read"), b"two");
        let names: Vec<_> = fs::read_dir(&dir).expect("list").map(|e| e.expect("entry").file_name()).collect();
        assert_eq!(names, vec![OsString::from("a.txt")]);
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_removes_the_temporary() {
        let dir = scratch("fail");
        let path = dir.join("b.txt");
        write_bytes(&path, b"old").expect("first write");
        let e = write_with(&path, |tmp| {
            fs::write(tmp, b"half").map_err(|e| e.to_string())?;
            Err("disk full".to_string())
        })
        .expect_err("the closure failed");
        assert_eq!(e.path, path);
        assert_eq!(e.reason, "disk full");
        assert_eq!(fs::read(&path).expect("read"), b"old");
        assert!(!temp_path(&path).expect("temp").exists(), "temporary file left");
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_file() {
        let path = Path::new("/nonexistent/porosph/c.png");
        let e = write_bytes(path, b"x").expect_err("no such directory");
        assert!(e.to_string().starts_with("/nonexistent/porosph/c.png: cannot write"), "{e}");
    }
}
