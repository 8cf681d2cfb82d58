//! Writing files atomically: a reader of the target sees the old file or the complete new one,
//! never half of it, and a failed or interrupted write leaves the target as it was.
//!
//! The new contents go to a temporary file in the target's folder, are flushed to disk, and
//! are then put in place in one step: renamed over the target ([`Replace::Always`]), or
//! hard-linked to its name ([`Replace::Never`]), which the file system refuses if anything has
//! that name at that moment, so that a file created while the contents were being written is
//! never replaced (checking first and renaming later would replace it).
//!
//! - A symbolic link is written through: the file it names is replaced, the link is kept.
//! - A device, named pipe or socket (`/dev/null`, a pipe a reader waits on) is written into in
//!   place, with either [`Replace`]: nothing the user has is replaced, and renaming over it
//!   would put a regular file in its place.
//! - Every error is an [`std::io::Error`] of its cause's kind (`NotFound` for a missing folder,
//!   `AlreadyExists` for [`Replace::Never`] refusing) whose message names the path.
//! - [`remove_temporaries`] is for an interrupt handler: it removes the temporary files of the
//!   writes in progress.
//!
//! ```
//! use std::io::Write;
//! use hbv::atomic_file::{write_atomically, Replace};
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("out.txt");
//! write_atomically(&path, Replace::Never, |f| f.write_all(b"first")).unwrap();
//! let refused = write_atomically(&path, Replace::Never, |f| f.write_all(b"second"));
//! assert_eq!(refused.unwrap_err().kind(), std::io::ErrorKind::AlreadyExists);
//! write_atomically(&path, Replace::Always, |f| f.write_all(b"third")).unwrap();
//! assert_eq!(std::fs::read(&path).unwrap(), b"third");
//! ```

mod staged;
mod target;
mod temporary;

use std::fs::File;
use std::io::{self, Write};
use std::path::Path;

pub use staged::{commit_all, stage, Staged};
pub use target::{check_writable, would_replace};
pub use temporary::remove_temporaries;

/// Whether a write may replace a file that exists at its path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Replace {
    /// Replace whatever file is there (`--force`, `overwrite=True`).
    Always,
    /// Fail with [`io::ErrorKind::AlreadyExists`] if a file, a folder or a link (even a
    /// dangling one) has the name when the write is put in place; checked atomically.
    Never,
}

/// Writes the file at `path` through `write`, atomically (see the [module](self)).
///
/// `write` fills the new file; it must flush any buffering it adds (a `BufWriter` dropped
/// unflushed swallows its errors). If anything fails — `write` itself, the flush to disk, the
/// rename or link — the temporary file is removed and whatever was at `path` is left untouched.
pub fn write_atomically(
    path: &Path,
    replace: Replace,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<()> {
    stage(path, replace, write)?.commit()
}

/// Writes several files all or none: each is written to its temporary file and flushed before
/// any is put in place ([`commit_all`]), so that a failing last one (a full disk, a missing
/// folder) leaves none of the others behind.
pub fn write_all_atomically(files: &[(&Path, &[u8])], replace: Replace) -> io::Result<()> {
    let staged = files
        .iter()
        .map(|(path, bytes)| stage(path, replace, |f| f.write_all(bytes)))
        .collect::<io::Result<Vec<Staged>>>()?;
    commit_all(staged)
}
