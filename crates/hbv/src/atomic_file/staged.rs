//! A file written to a temporary file beside its target and flushed to disk, then put in place:
//! renamed over the target ([`Replace::Always`]) or hard-linked to its name, which fails if
//! anything has that name at that moment ([`Replace::Never`]).

use std::fs::{self, File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};

use super::target::{target, through_links, would_replace, Target};
use super::temporary::Temporary;
use super::Replace;

/// A file written and flushed, not yet in place: [`Staged::commit`] or [`commit_all`] puts it
/// there. Dropped uncommitted, its temporary file is removed and the target is untouched.
#[must_use = "a staged file is written only when committed"]
pub struct Staged {
    /// The target, links followed.
    path: PathBuf,
    /// Its folder, synced once the target is in place.
    dir: PathBuf,
    replace: Replace,
    /// `None` for a device, pipe or socket (written in place already), or once renamed.
    temporary: Option<Temporary>,
}

/// Writes the file that `path` will be through `write`, up to putting it in place: a new
/// temporary file `.{name}.tmp-{pid}-{n}` in `path`'s folder is filled by `write` and flushed to
/// disk. A device, pipe or socket is written into in place here (nothing can replace it
/// atomically); a link is written through.
///
/// With [`Replace::Never`], something at `path` already is refused here, before `write` runs;
/// the commit checks again, atomically. On any error the temporary file is removed.
pub fn stage(
    path: &Path,
    replace: Replace,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<Staged> {
    let asked = path;
    let path = through_links(asked);
    let fail = |e: io::Error, what: &str| {
        io::Error::new(
            e.kind(),
            format!("cannot write {}: {what}: {e}", path.display()),
        )
    };
    let (name, dir) = match target(&path)? {
        Target::InPlace => {
            let mut file = OpenOptions::new()
                .write(true)
                .open(&path)
                .map_err(|e| fail(e, "cannot open it"))?;
            write(&mut file).map_err(|e| fail(e, "writing failed"))?;
            return Ok(Staged {
                path,
                dir: PathBuf::new(),
                replace,
                temporary: None,
            });
        }
        Target::Replace { name, dir } => (name, dir),
    };
    if replace == Replace::Never && would_replace(asked) {
        return Err(exists(asked));
    }
    let (temporary, mut file) = Temporary::create(&dir, &name).map_err(|e| {
        fail(
            e,
            &format!("cannot create a temporary file in {}", dir.display()),
        )
    })?;
    write(&mut file)
        .and_then(|()| file.sync_all())
        .map_err(|e| fail(e, "writing failed"))?;
    Ok(Staged {
        path,
        dir,
        replace,
        temporary: Some(temporary),
    })
}

impl Staged {
    /// The file this will be, links followed.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Puts the file in place; on failure the temporary file is removed and the target is left
    /// as it was.
    pub fn commit(self) -> io::Result<()> {
        commit_all(vec![self])
    }

    /// Links the temporary file to the target's name, failing if the name is taken. On a file
    /// system without hard links (FAT, some network and FUSE file systems) it checks and renames
    /// instead: there a file appearing in between could still be replaced.
    fn link_into_place(&mut self) -> io::Result<()> {
        let Some(temporary) = &self.temporary else {
            return Ok(());
        };
        match fs::hard_link(temporary.path(), &self.path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Err(exists(&self.path)),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::Unsupported | io::ErrorKind::PermissionDenied
                ) =>
            {
                if fs::symlink_metadata(&self.path).is_ok() {
                    return Err(exists(&self.path));
                }
                self.rename_into_place()
            }
            Err(e) => Err(io::Error::new(
                e.kind(),
                format!(
                    "cannot write {}: cannot link {} to it: {e}",
                    self.path.display(),
                    temporary.path().display()
                ),
            )),
        }
    }

    fn rename_into_place(&mut self) -> io::Result<()> {
        let Some(temporary) = self.temporary.take() else {
            return Ok(());
        };
        match fs::rename(temporary.path(), &self.path) {
            Ok(()) => {
                temporary.renamed();
                Ok(())
            }
            Err(e) => {
                let message = format!(
                    "cannot write {}: cannot rename {} over it: {e}",
                    self.path.display(),
                    temporary.path().display()
                );
                self.temporary = Some(temporary);
                Err(io::Error::new(e.kind(), message))
            }
        }
    }

    /// Takes back a link made by [`Staged::link_into_place`], if the name still holds this
    /// file: the name was free before, so removing it restores what was there.
    fn unlink(&self) {
        if let Some(temporary) = &self.temporary {
            if same_file(temporary.path(), &self.path) {
                let _ = fs::remove_file(&self.path);
            }
        }
    }
}

/// Puts several staged files in place, all or none as far as the file system allows: the
/// [`Replace::Never`] ones are linked first, and if one of them (or a later rename) fails, the
/// links made are taken back; then the [`Replace::Always`] ones are renamed, which cannot be
/// undone, so a rename failing after another succeeded (on a working file system, rare) leaves
/// the earlier ones written.
pub fn commit_all(mut staged: Vec<Staged>) -> io::Result<()> {
    let undo = |staged: &[Staged], linked: &[usize]| {
        for &i in linked {
            staged[i].unlink();
        }
    };
    let mut linked = Vec::new();
    for i in 0..staged.len() {
        if staged[i].replace == Replace::Never {
            if let Err(e) = staged[i].link_into_place() {
                undo(&staged, &linked);
                return Err(e);
            }
            linked.push(i);
        }
    }
    for i in 0..staged.len() {
        if staged[i].replace == Replace::Always {
            if let Err(e) = staged[i].rename_into_place() {
                undo(&staged, &linked);
                return Err(e);
            }
        }
    }
    let dirs: Vec<PathBuf> = staged.iter().map(|s| s.dir.clone()).collect();
    // The temporary files of the linked ones go now, before their folders are synced.
    drop(staged);
    for (i, dir) in dirs.iter().enumerate() {
        if !dir.as_os_str().is_empty() && !dirs[..i].contains(dir) {
            // Makes the rename or link durable; not every platform can open a folder for it.
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
        }
    }
    Ok(())
}

/// The error of [`Replace::Never`] finding something at `path`.
fn exists(path: &Path) -> io::Error {
    io::Error::new(
        io::ErrorKind::AlreadyExists,
        format!("cannot write {}: it exists already", path.display()),
    )
}

/// Whether two paths name the same file (the same inode); `false` where that cannot be told.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (fs::symlink_metadata(a), fs::symlink_metadata(b)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (a, b);
        false
    }
}
