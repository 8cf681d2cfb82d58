//! Replacing a file atomically: readers see either the old file or the complete new one.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Tells apart the temporary files of concurrent writers in one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary files being written now, for [`remove_temporaries`].
static IN_PROGRESS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Removes the temporary files of every write still in progress: for the handler of an
/// interrupt (Ctrl-C, SIGTERM), which then ends the process. The outputs themselves are left
/// as they were: a write is either renamed into place whole, or not at all.
pub fn remove_temporaries() {
    let in_progress = IN_PROGRESS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    for path in in_progress.iter() {
        let _ = fs::remove_file(path);
    }
}

/// Adds (`true`) or forgets a temporary file of [`IN_PROGRESS`].
fn track(path: &Path, writing: bool) {
    let mut in_progress = IN_PROGRESS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if writing {
        in_progress.push(path.to_path_buf());
    } else {
        in_progress.retain(|p| p != path);
    }
}

/// Writes a file at `path` through `write`, atomically.
///
/// `write` fills a new temporary file `.{name}.tmp-{pid}-{n}` in the same directory as `path`;
/// the file is then flushed to disk and renamed over `path`. If anything fails — `write` itself,
/// the flush or the rename — the temporary file is removed and whatever was at `path` before is
/// left untouched. `write` must flush any buffering it adds (a `BufWriter` dropped unflushed
/// swallows its errors).
///
/// A symbolic link at `path` is written through: the file it points to is replaced, the link is
/// kept. A path that is not a regular file but exists — a device such as `/dev/null`, a named
/// pipe, a socket — is written into in place, since nothing there can be replaced atomically
/// (renaming over it would put a regular file in the device's place); a directory is refused.
///
/// Every error names `path` and keeps the [`io::ErrorKind`] of its cause; a parent directory that
/// does not exist is reported as such.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<()> {
    let path = &through_links(path);
    let fail = |e: io::Error, what: &str| {
        io::Error::new(
            e.kind(),
            format!("cannot write {}: {what}: {e}", path.display()),
        )
    };
    match fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(io::Error::new(
                io::ErrorKind::IsADirectory,
                format!("cannot write {}: it is a directory", path.display()),
            ))
        }
        Ok(m) if !m.is_file() => {
            let mut file = OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| fail(e, "cannot open it"))?;
            return write(&mut file).map_err(|e| fail(e, "writing failed"));
        }
        _ => {}
    }
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("cannot write {}: not a file name", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(io::Error::new(
                io::ErrorKind::NotADirectory,
                format!(
                    "cannot write {}: {} is not a directory",
                    path.display(),
                    dir.display()
                ),
            ))
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            return Err(io::Error::new(
                io::ErrorKind::NotFound,
                format!(
                    "cannot write {}: directory {} does not exist",
                    path.display(),
                    dir.display()
                ),
            ))
        }
        Err(e) => {
            return Err(fail(
                e,
                &format!("cannot access directory {}", dir.display()),
            ))
        }
    }

    let (tmp_path, mut file) = create_temporary(dir, name).map_err(|e| {
        fail(
            e,
            &format!("cannot create a temporary file in {}", dir.display()),
        )
    })?;
    track(&tmp_path, true);
    let result = write(&mut file)
        .and_then(|()| file.sync_all())
        .map_err(|e| fail(e, "writing failed"))
        .and_then(|()| {
            drop(file);
            fs::rename(&tmp_path, path)
                .map_err(|e| fail(e, &format!("cannot rename {} over it", tmp_path.display())))
        });
    if result.is_err() {
        let _ = fs::remove_file(&tmp_path);
    }
    track(&tmp_path, false);
    match result {
        Ok(()) => {
            // Make the rename itself durable; not every platform can open a directory for this.
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
            Ok(())
        }
        Err(e) => Err(e),
    }
}

/// Whether writing `path` would replace something the user has, and so needs `--force`: a
/// regular file or a directory (through links), or a dangling link. A device, a named pipe or a
/// socket is not in the way: it is written into, not replaced ([`write_atomically`]).
pub fn in_the_way(path: &Path) -> bool {
    match fs::metadata(path) {
        Ok(m) => m.is_file() || m.is_dir(),
        Err(_) => fs::symlink_metadata(path).is_ok(),
    }
}

/// `path` with symbolic links followed to the path they name (existing or not), up to 40 links.
fn through_links(path: &Path) -> PathBuf {
    let mut path = path.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&path) {
            Ok(m) if m.file_type().is_symlink() => match fs::read_link(&path) {
                Ok(target) if target.is_absolute() => path = target,
                Ok(target) => path = path.parent().unwrap_or_else(|| Path::new(".")).join(target),
                Err(_) => break,
            },
            _ => break,
        }
    }
    path
}

/// Creates a new, empty temporary file for `name` in `dir`, never reusing an existing file.
fn create_temporary(dir: &Path, name: &std::ffi::OsStr) -> io::Result<(PathBuf, File)> {
    let mut tries = 0;
    loop {
        let mut tmp = OsString::from(".");
        tmp.push(name);
        tmp.push(format!(
            ".tmp-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let tmp_path = dir.join(tmp);
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp_path)
        {
            Ok(file) => return Ok((tmp_path, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && tries < 100 => tries += 1,
            Err(e) => return Err(e),
        }
    }
}
