//! The interrupt handler's clean-up, alone in its test binary: `remove_temporaries` removes
//! the temporary files of every write in progress in the process, and would reach the other
//! tests' writes if it ran beside them.

use std::io::{self, Write};

use hbv::atomic_file::{remove_temporaries, write_atomically, Replace};

/// An interrupt's handler removes the temporary file of a write in progress (the output is
/// left as it was: here, absent).
#[test]
fn an_interrupt_removes_the_temporary_file_of_a_write_in_progress() {
    let dir = tempfile::TempDir::new().unwrap();
    let path = dir.path().join("out.bin");
    let entries = || std::fs::read_dir(dir.path()).unwrap().count();
    let e = write_atomically(&path, Replace::Never, |f| {
        f.write_all(b"half")?;
        assert_eq!(entries(), 1, "the temporary file");
        remove_temporaries();
        assert_eq!(entries(), 0);
        Err(io::Error::other("interrupted"))
    })
    .unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains("out.bin") && message.contains("interrupted"),
        "{message}"
    );
    assert_eq!(entries(), 0);
}
