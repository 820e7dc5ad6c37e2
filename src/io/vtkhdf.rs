//! VTKHDF PolyData frames. (placeholder: being written)
use super::{Frame, IoError};
use std::path::Path;

/// Writes one frame to `path` (via a temporary name and a rename).
pub fn write_frame(_path: &Path, _frame: &Frame) -> Result<(), IoError> {
    unimplemented!("vtkhdf")
}

/// Reads a frame written by [`write_frame`].
pub fn read_frame(_path: &Path) -> Result<Frame, IoError> {
    unimplemented!("vtkhdf")
}

/// A human-readable summary of a frame file, for `porosph inspect`.
pub fn inspect_frame(_path: &Path) -> Result<String, IoError> {
    unimplemented!("vtkhdf")
}
