//! Writing `.npz` archives (uncompressed, members `NAME.npy`, as `numpy.savez` writes them) as a
//! stream, with the writer's own error as the only report of a failure.
//!
//! `ndarray_npy::NpzWriter` needs a seekable output and wraps `zip::ZipWriter`, which finishes
//! the archive again when it is dropped and prints any error of that to stderr ("ZipWriter drop
//! failed: ..."): on a full disk that line came before hbv's own message, and a pipe could not
//! be written at all ("Illegal seek"). Here the archive is written in the zip crate's streaming
//! mode (sizes in data descriptors after each member, which NumPy and the zip crate read), and
//! the output is wrapped so that after its first error nothing more reaches it: the first error
//! goes back to the caller unchanged ("No space left on device"), and a drop finds nothing to
//! report.

use std::io::{self, Write};

use ndarray_npy::{WriteNpyError, WriteNpyExt};
use zip::result::ZipError;
use zip::write::{SimpleFileOptions, StreamWriter};
use zip::{CompressionMethod, ZipWriter};

/// An `.npz` archive being written to `W`.
pub struct NpzStream<W: Write> {
    /// `None` once finished or abandoned.
    zip: Option<ZipWriter<StreamWriter<DiscardAfterError<W>>>>,
}

impl<W: Write> NpzStream<W> {
    /// Starts an archive on `out`.
    pub fn new(out: W) -> Self {
        let out = DiscardAfterError {
            inner: out,
            failed: false,
        };
        Self {
            zip: Some(ZipWriter::new_stream(out)),
        }
    }

    /// Adds member `name` (stored as `name.npy`, as NumPy does). An error is the output's own
    /// where the output failed; the archive is then to be dropped.
    pub fn add(&mut self, name: &str, array: &impl WriteNpyExt) -> io::Result<()> {
        let zip = self.zip.as_mut().expect("added to before finishing");
        let options = SimpleFileOptions::default().compression_method(CompressionMethod::Stored);
        zip.start_file(format!("{name}.npy"), options)
            .map_err(|e| io_error(e, name))?;
        array.write_npy(&mut *zip).map_err(|e| match e {
            WriteNpyError::Io(e) => e,
            e => io::Error::other(format!("member {name}: {e}")),
        })
    }

    /// Writes the central directory and flushes the output.
    pub fn finish(mut self) -> io::Result<()> {
        let zip = self.zip.take().expect("finished once");
        let mut out = zip.finish().map_err(|e| io_error(e, "(directory)"))?;
        out.flush()
    }
}

/// An archive dropped unfinished (after an error) is not finished: the zip crate would try,
/// and print to stderr if that failed.
impl<W: Write> Drop for NpzStream<W> {
    fn drop(&mut self) {
        if let Some(zip) = self.zip.take() {
            // Leaks the list of members written so far (a few hundred bytes); the output itself
            // is borrowed or owned by the caller's error path, which removes it.
            std::mem::forget(zip);
        }
    }
}

/// The output's error where the zip crate passes one on, else the zip crate's reason.
fn io_error(e: ZipError, member: &str) -> io::Error {
    match e {
        ZipError::Io(e) => e,
        e => io::Error::other(format!("member {member}: {e}")),
    }
}

/// `inner`, until it fails: its first error is returned as it is, and every later write or
/// flush is taken without reaching it, so that nothing written after a failure can fail again
/// (the zip crate finishing an archive inside its own error path, then printing).
struct DiscardAfterError<W> {
    inner: W,
    failed: bool,
}

impl<W: Write> DiscardAfterError<W> {
    fn note<T>(&mut self, result: io::Result<T>) -> io::Result<T> {
        if result
            .as_ref()
            .is_err_and(|e| e.kind() != io::ErrorKind::Interrupted)
        {
            self.failed = true;
        }
        result
    }
}

impl<W: Write> Write for DiscardAfterError<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.failed {
            return Ok(buf.len());
        }
        let result = self.inner.write(buf);
        self.note(result)
    }

    fn flush(&mut self) -> io::Result<()> {
        if self.failed {
            return Ok(());
        }
        let result = self.inner.flush();
        self.note(result)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array1;

    /// Fails every write after `room` bytes, as a full disk does.
    struct FullAfter {
        room: usize,
        written: Vec<u8>,
    }

    impl Write for FullAfter {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.written.len() + buf.len() > self.room {
                return Err(io::Error::from_raw_os_error(28)); // ENOSPC
            }
            self.written.extend_from_slice(buf);
            Ok(buf.len())
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    fn archive(out: &mut FullAfter) -> io::Result<()> {
        let mut npz = NpzStream::new(out);
        npz.add("t", &Array1::from(vec![1.0f32, 2.0, 3.0]))?;
        npz.add("hit", &Array1::from(vec![true, false, true]))?;
        npz.finish()
    }

    #[test]
    fn an_archive_reads_back_member_by_member() {
        let mut out = FullAfter {
            room: usize::MAX,
            written: Vec::new(),
        };
        archive(&mut out).unwrap();
        let mut zip = zip::ZipArchive::new(io::Cursor::new(out.written)).unwrap();
        let names: Vec<&str> = zip.file_names().collect();
        assert_eq!(names, ["t.npy", "hit.npy"]);
        let mut t = Vec::new();
        io::Read::read_to_end(&mut zip.by_name("t.npy").unwrap(), &mut t).unwrap();
        assert!(t.starts_with(b"\x93NUMPY"));
    }

    /// The output's error comes back as it is, wherever the output fills up.
    #[test]
    fn a_full_output_gives_its_own_error_wherever_it_fills() {
        for room in [0, 10, 100, 200, 300] {
            let mut out = FullAfter {
                room,
                written: Vec::new(),
            };
            let e = archive(&mut out).unwrap_err();
            assert_eq!(e.raw_os_error(), Some(28), "{room}: {e}");
        }
    }
}
