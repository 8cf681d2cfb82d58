//! The temporary files of writes in progress: a unique name beside each target, and the
//! registry that an interrupt handler empties.

use std::ffi::{OsStr, OsString};
use std::fs::{self, File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

/// Tells apart the temporary files of concurrent writes in one process: two threads saving the
/// same path at once each get their own (a name of the process id alone made them collide).
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary files that exist now, for [`remove_temporaries`].
static IN_PROGRESS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The registry, even if a thread panicked while holding it: a list of paths cannot be left
/// half-changed by a panic, and the interrupt handler must still reach it.
fn in_progress() -> MutexGuard<'static, Vec<PathBuf>> {
    IN_PROGRESS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Removes the temporary files of every write still in progress in this process: for the
/// handler of an interrupt (Ctrl-C, SIGTERM), which then ends the process without running the
/// writers' own clean-up. The targets are left as they were: each write is put in place whole
/// or not at all.
pub fn remove_temporaries() {
    for path in in_progress().iter() {
        let _ = fs::remove_file(path);
    }
}

/// A temporary file `.{name}.tmp-{pid}-{n}` in the target's folder (so that the rename or link
/// that puts it in place stays on one file system), `name` shortened where the whole would be
/// too long a file name. Dropped, it is removed.
pub(super) struct Temporary {
    path: PathBuf,
}

impl Temporary {
    /// Creates a new, empty temporary file for the target `name` in `dir`, never opening a file
    /// that exists already, and registers it for [`remove_temporaries`].
    pub(super) fn create(dir: &Path, name: &OsStr) -> io::Result<(Temporary, File)> {
        let mut tries = 0;
        loop {
            let suffix = format!(
                ".tmp-{}-{}",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            );
            let path = dir.join(temporary_name(name, &suffix));
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    in_progress().push(path.clone());
                    return Ok((Temporary { path }, file));
                }
                // Left by a process of the same id that was killed: take the next number.
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && tries < 100 => tries += 1,
                Err(e) => return Err(e),
            }
        }
    }

    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Forgets the temporary file once it has been renamed into place (nothing is left to
    /// remove under its name).
    pub(super) fn renamed(self) {
        unregister(&self.path);
        std::mem::forget(self);
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        let _ = fs::remove_file(&self.path);
        unregister(&self.path);
    }
}

/// The longest file name of the common file systems (ext4, XFS, APFS, NTFS: 255 bytes, or
/// UTF-16 units, which a UTF-8 name has at most as many of as bytes).
const NAME_MAX: usize = 255;

/// `.{name}{suffix}`, with `name` cut short so that the whole fits in [`NAME_MAX`] bytes: a
/// target whose own name is near the limit can still be written (its temporary name would
/// otherwise be refused as too long). The suffix keeps the names unique.
fn temporary_name(name: &OsStr, suffix: &str) -> OsString {
    let room = NAME_MAX.saturating_sub(1 + suffix.len());
    let mut file_name = OsString::from(".");
    file_name.push(shortened(name, room));
    file_name.push(suffix);
    file_name
}

/// The first `room` bytes of `name` at most.
#[cfg(unix)]
fn shortened(name: &OsStr, room: usize) -> &OsStr {
    use std::os::unix::ffi::OsStrExt;
    let bytes = name.as_bytes();
    OsStr::from_bytes(&bytes[..bytes.len().min(room)])
}

/// The first `room` bytes of `name` at most, cut between characters (a name that is not
/// Unicode is kept whole).
#[cfg(not(unix))]
fn shortened(name: &OsStr, room: usize) -> &OsStr {
    match name.to_str() {
        Some(text) if text.len() > room => {
            let end = (0..=room)
                .rev()
                .find(|&k| text.is_char_boundary(k))
                .unwrap_or(0);
            OsStr::new(&text[..end])
        }
        _ => name,
    }
}

fn unregister(path: &Path) {
    in_progress().retain(|p| p != path);
}
