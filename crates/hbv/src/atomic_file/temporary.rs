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
/// that puts it in place stays on one file system). Dropped, it is removed.
pub(super) struct Temporary {
    path: PathBuf,
}

impl Temporary {
    /// Creates a new, empty temporary file for the target `name` in `dir`, never opening a file
    /// that exists already, and registers it for [`remove_temporaries`].
    pub(super) fn create(dir: &Path, name: &OsStr) -> io::Result<(Temporary, File)> {
        let mut tries = 0;
        loop {
            let mut file_name = OsString::from(".");
            file_name.push(name);
            file_name.push(format!(
                ".tmp-{}-{}",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            let path = dir.join(file_name);
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

fn unregister(path: &Path) {
    in_progress().retain(|p| p != path);
}
