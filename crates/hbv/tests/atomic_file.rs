//! `hbv::atomic_file` from the outside: targets replaced whole or not at all, devices and pipes
//! written in place, links written through, `Replace::Never` refusing atomically, concurrent
//! writers, and several files written all or none.

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Barrier};

use hbv::atomic_file::{
    commit_all, stage, write_all_atomically, write_atomically, Replace, Staged,
};

fn entries(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "{message:?} should mention {part:?}"
        );
    }
}

#[test]
fn a_file_is_replaced_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.bin");
    write_atomically(&path, Replace::Never, |f| f.write_all(b"new file")).unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"new file");
    let e = write_atomically(&path, Replace::Never, |f| f.write_all(b"x")).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
    assert_mentions(&e.to_string(), &["out.bin", "exists"]);
    write_atomically(&path, Replace::Always, |f| f.write_all(b"new contents")).unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"new contents");
    assert_eq!(entries(dir.path()), vec![path]);
}

/// A target whose name is as long as a file name may be (255 bytes) is written: the temporary
/// file's name, the target's with a dot and a suffix, is cut short to fit (it was refused as
/// too long). Both modes, and a name of multi-byte characters.
#[test]
fn a_name_of_the_longest_length_is_written() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["n".repeat(255), "é".repeat(127)] {
        let path = dir.path().join(&name);
        write_atomically(&path, Replace::Never, |f| f.write_all(b"first")).unwrap();
        write_atomically(&path, Replace::Always, |f| f.write_all(b"second")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"second");
    }
    assert_eq!(entries(dir.path()).len(), 2, "no temporary left behind");
}

/// A symbolic link is written through: its target gets the new contents, the link stays a link.
/// Without replacing, a link to a file and a dangling link are both something in the way.
#[cfg(unix)]
#[test]
fn links_are_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("target.bin");
    let link = dir.path().join("link.bin");
    fs::write(&target, b"old").unwrap();
    std::os::unix::fs::symlink("target.bin", &link).unwrap();
    let e = write_atomically(&link, Replace::Never, |f| f.write_all(b"x")).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
    write_atomically(&link, Replace::Always, |f| f.write_all(b"new")).unwrap();
    assert!(fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(fs::read(&target).unwrap(), b"new");
    assert_eq!(entries(dir.path()), vec![link.clone(), target.clone()]);

    let dangling = dir.path().join("dangling.bin");
    std::os::unix::fs::symlink("nowhere.bin", &dangling).unwrap();
    let e = write_atomically(&dangling, Replace::Never, |f| f.write_all(b"x")).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
    write_atomically(&dangling, Replace::Always, |f| f.write_all(b"made")).unwrap();
    assert!(fs::symlink_metadata(&dangling)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(fs::read(dir.path().join("nowhere.bin")).unwrap(), b"made");
}

/// What is not a regular file is written into in place, never replaced, and needs no
/// `Replace::Always`: a named pipe (read by another process, as a user's reader would be),
/// `/dev/null`; `/dev/full` reports its error; a directory is refused.
#[cfg(unix)]
#[test]
fn devices_and_pipes_are_written_in_place() {
    use std::os::unix::fs::FileTypeExt;
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        let reader = Command::new("cat")
            .arg(&fifo)
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        write_atomically(&fifo, Replace::Never, |f| f.write_all(b"through the pipe")).unwrap();
        let read = reader.wait_with_output().unwrap();
        assert_eq!(read.stdout, b"through the pipe");
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
        assert_eq!(entries(dir.path()), vec![fifo]);
    }

    let null = Path::new("/dev/null");
    if fs::metadata(null).is_ok_and(|m| m.file_type().is_char_device()) {
        write_atomically(null, Replace::Never, |f| f.write_all(b"gone")).unwrap();
        write_atomically(null, Replace::Always, |f| f.write_all(b"gone")).unwrap();
        assert!(fs::metadata(null).unwrap().file_type().is_char_device());
    }
    let full = Path::new("/dev/full");
    if fs::metadata(full).is_ok_and(|m| m.file_type().is_char_device()) {
        let e = write_atomically(full, Replace::Always, |f| f.write_all(b"no room")).unwrap_err();
        assert_mentions(&e.to_string(), &["/dev/full", "writing failed"]);
        assert!(fs::metadata(full).unwrap().file_type().is_char_device());
    }
    for replace in [Replace::Always, Replace::Never] {
        let e = write_atomically(dir.path(), replace, |f| f.write_all(b"x")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::IsADirectory);
        assert_mentions(&e.to_string(), &["is a directory"]);
    }
}

/// A writer that fails leaves the old file as it was and no temporary file behind.
#[test]
fn a_failing_writer_keeps_the_old_file_and_leaves_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.bin");
    fs::write(&path, b"old").unwrap();
    let e = write_atomically(&path, Replace::Always, |f| {
        f.write_all(b"partial")?;
        Err(io::Error::other("disk on fire"))
    })
    .unwrap_err();
    assert_mentions(&e.to_string(), &["out.bin", "disk on fire"]);
    assert_eq!(fs::read(&path).unwrap(), b"old");
    assert_eq!(entries(dir.path()), vec![path.clone()]);

    // Also when nothing was there before.
    let fresh = dir.path().join("fresh.bin");
    for replace in [Replace::Always, Replace::Never] {
        assert!(write_atomically(&fresh, replace, |_| Err(io::Error::other("no"))).is_err());
    }
    assert_eq!(entries(dir.path()), vec![path]);
}

#[test]
fn a_missing_or_wrong_folder_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no/such/dir/hits.npz");
    let e = write_atomically(&path, Replace::Never, |f| f.write_all(b"x")).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::NotFound);
    assert_mentions(
        &e.to_string(),
        &["hits.npz", "no/such/dir", "does not exist"],
    );
    let file = dir.path().join("file");
    fs::write(&file, b"x").unwrap();
    let e = write_atomically(&file.join("x"), Replace::Never, |f| f.write_all(b"x")).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::NotADirectory);
    assert_mentions(&e.to_string(), &["file is not a directory"]);
}

#[cfg(unix)]
#[test]
fn a_read_only_folder_is_named() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let ro = dir.path().join("ro");
    fs::create_dir(&ro).unwrap();
    fs::set_permissions(&ro, fs::Permissions::from_mode(0o555)).unwrap();
    // Privileged users (root in a container) may write anyway; then there is nothing to test.
    let probe = ro.join("probe");
    if File::create(&probe).is_ok() {
        fs::remove_file(&probe).unwrap();
        return;
    }
    let path = ro.join("hits.npz");
    let e = write_atomically(&path, Replace::Always, |f| f.write_all(b"x")).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::PermissionDenied);
    assert_mentions(
        &e.to_string(),
        &["hits.npz", "cannot create a temporary file"],
    );
    fs::set_permissions(&ro, fs::Permissions::from_mode(0o755)).unwrap();
}

/// The gap between checking and putting in place is closed: a file that appears while the new
/// contents are written is kept, and the write fails as if it had been there from the start.
#[test]
fn never_refuses_a_file_that_appears_while_writing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.bin");
    let e = write_atomically(&path, Replace::Never, |f| {
        f.write_all(b"ours")?;
        fs::write(&path, b"theirs")
    })
    .unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
    assert_mentions(&e.to_string(), &["out.bin", "exists"]);
    assert_eq!(fs::read(&path).unwrap(), b"theirs");
    assert_eq!(entries(dir.path()), vec![path]);
}

/// Two threads writing the same path at once each stage their own temporary file (a name of
/// the process id alone made them collide): both succeed and one complete file is left. Without
/// replacing, exactly one succeeds.
#[test]
fn two_threads_writing_one_path_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.bin");
    let contents = [vec![b'a'; 1 << 20], vec![b'b'; 1 << 20]];
    for replace in [Replace::Always, Replace::Never] {
        let _ = fs::remove_file(&path);
        let both_writing = Arc::new(Barrier::new(2));
        let results: Vec<io::Result<()>> = std::thread::scope(|s| {
            let writers: Vec<_> = contents
                .iter()
                .map(|bytes| {
                    let both_writing = both_writing.clone();
                    let path = &path;
                    s.spawn(move || {
                        write_atomically(path, replace, |f| {
                            f.write_all(&bytes[..1000])?;
                            both_writing.wait();
                            f.write_all(&bytes[1000..])
                        })
                    })
                })
                .collect();
            writers.into_iter().map(|w| w.join().unwrap()).collect()
        });
        let succeeded = results.iter().filter(|r| r.is_ok()).count();
        match replace {
            Replace::Always => assert_eq!(succeeded, 2, "{results:?}"),
            Replace::Never => {
                assert_eq!(succeeded, 1, "{results:?}");
                let e = results.iter().find_map(|r| r.as_ref().err()).unwrap();
                assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
            }
        }
        let written = fs::read(&path).unwrap();
        assert!(contents.contains(&written), "a mixed or partial file");
        assert_eq!(entries(dir.path()), vec![path.clone()]);
    }
}

/// Several files are written all or none: a last one that cannot be written leaves none of the
/// others, and so does a last one whose name is taken while they are being put in place.
#[test]
fn several_files_are_written_all_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first.png");
    let missing = dir.path().join("no/such/second.png");
    let files: [(&Path, &[u8]); 2] = [(&first, b"1"), (&missing, b"2")];
    for replace in [Replace::Always, Replace::Never] {
        let e = write_all_atomically(&files, replace).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
        assert!(entries(dir.path()).is_empty());
    }

    let second = dir.path().join("second.png");
    let staged: Vec<Staged> = [&first, &second]
        .iter()
        .map(|p| stage(p, Replace::Never, |f| f.write_all(b"ours")))
        .collect::<io::Result<_>>()
        .unwrap();
    fs::write(&second, b"theirs").unwrap();
    let e = commit_all(staged).unwrap_err();
    assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
    assert_eq!(entries(dir.path()), vec![second.clone()]);
    assert_eq!(fs::read(&second).unwrap(), b"theirs");

    fs::remove_file(&second).unwrap();
    write_all_atomically(&[(&first, b"1"), (&second, b"2")], Replace::Never).unwrap();
    assert_eq!(fs::read(&first).unwrap(), b"1");
    assert_eq!(fs::read(&second).unwrap(), b"2");
}
