//! What is at an output path, and so how it is written: replaced through a temporary file in
//! its folder, or written into in place.

use std::ffi::OsString;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

/// How [`super::stage`] writes a path (links already followed).
pub(super) enum Target {
    /// A device, named pipe or socket: written into, since nothing can replace it atomically
    /// (renaming over `/dev/null`, as root, would put a regular file in its place).
    InPlace,
    /// A regular file or nothing yet: replaced by a temporary file named after `name` in `dir`.
    Replace { name: OsString, dir: PathBuf },
}

/// Where `path` (links already followed) is to be written, or why it cannot be: a directory is
/// refused, and so is a folder that does not exist or is not a folder.
pub(super) fn target(path: &Path) -> io::Result<Target> {
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
        Err(e) => Err(io::Error::new(
            e.kind(),
            format!(
                "cannot write {}: cannot access directory {}: {e}",
                path.display(),
                dir.display()
            ),
        )),
    }
}

/// Checks what a write checks before writing anything, so that a program can refuse an output
/// path before its work rather than after: `path` (through links) is not a directory, and its
/// folder exists and is one. The errors are the ones the write would give.
pub fn check_writable(path: &Path) -> io::Result<()> {
    target(&through_links(path)).map(|_| ())
}

/// Whether writing `path` would replace something the user has, which
/// [`Replace::Never`](super::Replace::Never) refuses: a regular file or a directory (through
/// links), or a dangling link. A device, a named pipe or a socket is not in the way: it is
/// written into, not replaced.
pub fn would_replace(path: &Path) -> bool {
    match fs::metadata(path) {
        Ok(m) => m.is_file() || m.is_dir(),
        Err(_) => fs::symlink_metadata(path).is_ok(),
    }
}

/// `path` with symbolic links followed to the path they name (existing or not), up to 40 links
/// (Linux's limit), so that the link is kept and the file it names is replaced.
pub(super) fn through_links(path: &Path) -> PathBuf {
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
