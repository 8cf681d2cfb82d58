//! Replacing a file atomically: readers see either the old file or the complete new one.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
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
    stage(path, write)?.commit()
}

/// Writes several files, each as [`write_atomically`] does, all or none: every file is written
/// to its temporary file and flushed first, and only then are they renamed into place. If any
/// write fails, no output is touched (a rename itself failing after others succeeded, on a
/// working file system, is the one case left).
pub fn write_all_atomically(files: &[(&Path, &[u8])]) -> io::Result<()> {
    let staged = files
        .iter()
        .map(|(path, bytes)| stage(path, |f| f.write_all(bytes)))
        .collect::<io::Result<Vec<Staged>>>()?;
    staged.into_iter().try_for_each(Staged::commit)
}

/// A file written to its temporary file and flushed, to be renamed into place by
/// [`Staged::commit`]; dropped uncommitted, the temporary file is removed.
#[must_use]
pub struct Staged {
    path: PathBuf,
    dir: PathBuf,
    /// `None` for a device, pipe or socket, written in place already.
    tmp: Option<PathBuf>,
}

impl Staged {
    /// Renames the temporary file over the path (and makes the rename durable where the
    /// platform can); on failure the temporary file is removed.
    pub fn commit(mut self) -> io::Result<()> {
        let Some(tmp) = self.tmp.take() else {
            return Ok(());
        };
        let renamed = fs::rename(&tmp, &self.path).map_err(|e| {
            io::Error::new(
                e.kind(),
                format!(
                    "cannot write {}: cannot rename {} over it: {e}",
                    self.path.display(),
                    tmp.display()
                ),
            )
        });
        if renamed.is_err() {
            let _ = fs::remove_file(&tmp);
        }
        track(&tmp, false);
        renamed?;
        // Make the rename itself durable; not every platform can open a directory for this.
        if let Ok(d) = File::open(&self.dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            let _ = fs::remove_file(&tmp);
            track(&tmp, false);
        }
    }
}

/// Where [`write_atomically`] would write `path`: in place (a device, pipe or socket), or
/// through a temporary file in a folder.
enum Target {
    InPlace,
    Replace { name: OsString, dir: PathBuf },
}

/// Checks what [`write_atomically`] checks before writing anything, so that a command can
/// refuse an output path before its work rather than after: `path` (through links) is not a
/// directory, and its folder exists and is one. The errors are the ones the write would give.
pub fn check_writable(path: &Path) -> io::Result<()> {
    target(&through_links(path)).map(|_| ())
}

/// Where `path` (links already followed) is to be written, or why it cannot be.
fn target(path: &Path) -> io::Result<Target> {
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
        Ok(m) if !m.is_file() => return Ok(Target::InPlace),
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
        Ok(m) if m.is_dir() => Ok(Target::Replace {
            name: name.to_owned(),
            dir: dir.to_path_buf(),
        }),
        Ok(_) => Err(io::Error::new(
            io::ErrorKind::NotADirectory,
            format!(
                "cannot write {}: {} is not a directory",
                path.display(),
                dir.display()
            ),
        )),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!(
                "cannot write {}: directory {} does not exist",
                path.display(),
                dir.display()
            ),
        )),
        Err(e) => Err(fail(
            e,
            &format!("cannot access directory {}", dir.display()),
        )),
    }
}

/// [`write_atomically`] up to the rename: the file written to its temporary file and flushed
/// (or, for a device, pipe or socket, written in place).
fn stage(path: &Path, write: impl FnOnce(&mut File) -> io::Result<()>) -> io::Result<Staged> {
    let path = &through_links(path);
    let fail = |e: io::Error, what: &str| {
        io::Error::new(
            e.kind(),
            format!("cannot write {}: {what}: {e}", path.display()),
        )
    };
    let (name, dir) = match target(path)? {
        Target::InPlace => {
            let mut file = OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| fail(e, "cannot open it"))?;
            write(&mut file).map_err(|e| fail(e, "writing failed"))?;
            return Ok(Staged {
                path: path.clone(),
                dir: PathBuf::new(),
                tmp: None,
            });
        }
        Target::Replace { name, dir } => (name, dir),
    };
    let (tmp_path, mut file) = create_temporary(&dir, &name).map_err(|e| {
        fail(
            e,
            &format!("cannot create a temporary file in {}", dir.display()),
        )
    })?;
    track(&tmp_path, true);
    // From here the staged file removes its temporary file if it is dropped uncommitted.
    let staged = Staged {
        path: path.clone(),
        dir,
        tmp: Some(tmp_path),
    };
    write(&mut file)
        .and_then(|()| file.sync_all())
        .map_err(|e| fail(e, "writing failed"))?;
    Ok(staged)
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
