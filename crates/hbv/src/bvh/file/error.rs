//! What can be wrong with a `.hbv` file.

use std::fmt;
use std::path::PathBuf;

use super::format::BvhFileKind;

/// A `.hbv` file that could not be loaded: the file, and what is wrong with it.
#[derive(Debug)]
pub struct BvhFileError {
    pub path: PathBuf,
    pub problem: BvhFileProblem,
}

/// What is wrong with a `.hbv` file.
#[derive(Debug)]
pub enum BvhFileProblem {
    /// The file could not be opened or read.
    Io(std::io::Error),
    /// It does not start with the `.hbv` magic number.
    NotBvhFile,
    /// Written by a newer hbv (or not a version this one knows).
    UnsupportedVersion { found: u32, supported: u32 },
    /// A file of the other kind: a scene given to a reader of one mesh, or the reverse.
    WrongKind {
        found: BvhFileKind,
        expected: BvhFileKind,
    },
    /// What is wrong with the `mesh`-th mesh file inside a scene file (counted from 0); a
    /// [`BvhFileProblem::Truncated`] inside it counts its bytes from the start of the scene file.
    InMesh {
        mesh: u64,
        problem: Box<BvhFileProblem>,
    },
    /// The byte-order mark is not `0x01020304` read little-endian.
    ByteOrder { found: u32 },
    /// The file ends inside `section`.
    Truncated {
        section: &'static str,
        needed: u64,
        len: u64,
    },
    /// The declared sizes do not fit in 64 bits, or in memory: the header lies.
    ImpossibleSize { section: &'static str },
    /// Bytes after the last section.
    TrailingBytes { expected: u64, len: u64 },
    /// A checksum does not match: the bytes were changed after writing.
    Checksum {
        part: &'static str,
        stored: u32,
        computed: u32,
    },
    /// Well-formed bytes that do not describe a valid tree and mesh.
    Invalid { place: String, reason: String },
}

impl fmt::Display for BvhFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.problem)
    }
}

impl fmt::Display for BvhFileProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BvhFileProblem::Io(e) => write!(f, "{e}"),
            BvhFileProblem::NotBvhFile => write!(
                f,
                "not an hbv BVH file (it does not start with the .hbv magic number)"
            ),
            BvhFileProblem::UnsupportedVersion { found, supported } if found > supported => {
                write!(
                    f,
                    "format version {found} is newer than this hbv reads ({supported}): \
                     upgrade hbv or rebuild the file with `hbv build`"
                )
            }
            BvhFileProblem::UnsupportedVersion { found, supported } => write!(
                f,
                "unknown format version {found} (this hbv reads versions 1 to {supported})"
            ),
            BvhFileProblem::WrongKind { found, expected } => write!(
                f,
                "the file holds {} (format version {}), not {}: read it as {}",
                found.contents(),
                found.version(),
                expected.contents(),
                found.contents()
            ),
            BvhFileProblem::InMesh { mesh, problem } => write!(f, "mesh {mesh}: {problem}"),
            BvhFileProblem::ByteOrder { found } => write!(
                f,
                "wrong byte-order mark {found:#010x} (expected 0x01020304): \
                 the file is not little-endian, or is corrupted"
            ),
            BvhFileProblem::Truncated {
                section,
                needed,
                len,
            } => write!(
                f,
                "the file is truncated: it ends in the {section} (the header declares at \
                 least {needed} bytes, the file has {len})"
            ),
            BvhFileProblem::ImpossibleSize { section } => write!(
                f,
                "the header declares an impossible size for the {section}: the file is corrupted"
            ),
            BvhFileProblem::TrailingBytes { expected, len } => write!(
                f,
                "{} unexpected bytes after the end of the data (the header declares {expected} \
                 bytes, the file has {len})",
                len - expected
            ),
            BvhFileProblem::Checksum {
                part,
                stored,
                computed,
            } => write!(
                f,
                "the {part} is corrupted: CRC-32 {computed:#010x} does not match the stored \
                 {stored:#010x}"
            ),
            BvhFileProblem::Invalid { place, reason } => write!(f, "{place}: {reason}"),
        }
    }
}

impl std::error::Error for BvhFileError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.problem {
            BvhFileProblem::Io(e) => Some(e),
            _ => None,
        }
    }
}
