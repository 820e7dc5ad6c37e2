//! How porosph opens HDF5 files: without file locks, and with close-on-exec.
//!
//! The HDF5 C library (1.10 and later) takes a `flock` on every file it
//! opens, exclusive for writing and shared for reading, and opens the file
//! without `O_CLOEXEC`. A process spawned by another thread while a file is
//! open (a test binary that writes frames while other tests start
//! `porosph`; a user's program that runs porosph as a library and spawns
//! children) inherits the descriptor, and with it the lock, which outlives
//! the writer's close: the next open of that file failed with "unable to
//! lock file, errno = 11" (`tests/hdf5_locks.rs`).
//!
//! porosph needs no locks: every frame and checkpoint is written to a fresh
//! temporary name and renamed into place, so no two writers and no writer
//! and reader ever share a file. So every open here turns HDF5's locking
//! off, which also lets `porosph render` and `inspect` read a file that
//! another program holds locked; and the descriptor is made close-on-exec
//! at once, so a child started later does not hold the file open.

use hdf5::plist::file_access::FileAccessBuilder;
use hdf5::{File, FileBuilder};
use std::path::Path;

/// The file-access settings of every porosph open.
fn unlocked(fapl: &mut FileAccessBuilder) -> &mut FileAccessBuilder {
    fapl.file_locking(false)
}

/// Opens an existing file read-only.
pub fn open(path: &Path) -> hdf5::Result<File> {
    let file = FileBuilder::new().with_fapl(unlocked).open(path)?;
    close_on_exec(&file);
    Ok(file)
}

/// Creates (or truncates) a file for writing, in the current file format.
pub fn create(path: &Path) -> hdf5::Result<File> {
    let file = FileBuilder::new().with_fapl(unlocked).create(path)?;
    close_on_exec(&file);
    Ok(file)
}

/// Creates (or truncates) a file for writing whose objects are readable by
/// HDF5 1.8 and later (checkpoints).
pub fn create_v18(path: &Path) -> hdf5::Result<File> {
    let file = FileBuilder::new().with_fapl(|p| unlocked(p).libver_v18()).create(path)?;
    close_on_exec(&file);
    Ok(file)
}

/// Sets `FD_CLOEXEC` on the descriptor HDF5 opened for `file` (the default
/// sec2 driver keeps one `int` descriptor). Best effort: a driver without a
/// descriptor is left as it is; with locking off an inherited descriptor
/// holds no lock in any case.
fn close_on_exec(file: &File) {
    let mut handle: *mut std::ffi::c_void = std::ptr::null_mut();
    // SAFETY: H5Fget_vfd_handle writes the driver's handle pointer for a
    // valid file id and the default access list; for sec2 it points to the
    // driver's `int` descriptor, which lives as long as the file is open.
    let status =
        unsafe { hdf5_sys::h5f::H5Fget_vfd_handle(file.id(), hdf5_sys::h5p::H5P_DEFAULT, &mut handle as *mut *mut _) };
    if status < 0 || handle.is_null() {
        return;
    }
    // SAFETY: see above; fcntl on a descriptor that is open.
    unsafe {
        let fd = *(handle as *const libc::c_int);
        let flags = libc::fcntl(fd, libc::F_GETFD);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC);
        }
    }
}
