//! The byte layout of `.hbv` mesh files, version 1, and the preamble every `.hbv` file starts
//! with (scene files, version 2, are laid out in `scene_format.rs`). Everything is little-endian.
//!
//! ```text
//! offset size  header (64 bytes)
//!      0    8  magic  89 48 42 56 0D 0A 1A 0A  ("\x89HBV\r\n\x1a\n", PNG-style: catches
//!                     text-mode newline conversion and 7-bit transfers)
//!      8    4  u32 format version (1)
//!     12    4  u32 byte-order mark 0x01020304 (bytes 04 03 02 01)
//!     16    4  u32 header size (64)
//!     20    4  u32 settings length S in bytes (at most 65536)
//!     24    8  u64 vertex count V
//!     32    8  u64 triangle count T
//!     40    8  u64 node count N
//!     48    8  u64 leaf entry count L
//!     56    4  u32 CRC-32 of the payload (every byte after the header)
//!     60    4  u32 CRC-32 of header bytes 0..60
//! payload, in this order:
//!   settings   S bytes of UTF-8, zero-padded to a multiple of 4
//!   positions  V × 3 f32 (x, y, z)
//!   triangles  T × 3 u32 vertex indices
//!   nodes      N × 32 bytes: min xyz f32, max xyz f32, u32 first, u32 count | leaf bit (1 << 31)
//!              node 0 is the root; an internal node's children are nodes first..first+count
//!              (first > its own index), a leaf's triangles are leaf entries first..first+count
//!   leaves     L × u32 triangle ids
//! ```

use super::error::BvhFileProblem;

/// The first 8 bytes of every `.hbv` file.
pub const MAGIC: [u8; 8] = *b"\x89HBV\r\n\x1a\n";
/// The newest version this build reads: version 1 files hold one mesh, version 2 files a scene.
pub const FORMAT_VERSION: u32 = SCENE_FORMAT_VERSION;
/// The version of files that hold one mesh and its tree ([`BvhFile`](super::BvhFile)). Mesh
/// files are still written as version 1, so that every hbv that reads `.hbv` files reads them.
pub const MESH_FORMAT_VERSION: u32 = 1;
/// The version of files that hold a scene ([`Scene::save`](crate::scene::Scene::save)).
pub const SCENE_FORMAT_VERSION: u32 = 2;
pub(super) const BYTE_ORDER_MARK: u32 = 0x0102_0304;
pub(super) const HEADER_SIZE: usize = 64;
pub(super) const NODE_SIZE: usize = 32;
pub(super) const LEAF_BIT: u32 = 1 << 31;
pub(super) const MAX_SETTINGS: u32 = 1 << 16;

/// The header's fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Header {
    pub settings_len: u32,
    pub vertices: u64,
    pub triangles: u64,
    pub nodes: u64,
    pub leaf_entries: u64,
    pub payload_crc: u32,
}

/// What a `.hbv` file holds, told by its format version.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BvhFileKind {
    /// One mesh and its tree (version 1): [`BvhFile`](super::BvhFile).
    Mesh,
    /// Meshes, their trees and the instances placing them (version 2):
    /// [`Scene`](crate::scene::Scene).
    Scene,
}

impl BvhFileKind {
    /// The format version files of this kind are written in.
    pub const fn version(self) -> u32 {
        match self {
            BvhFileKind::Mesh => MESH_FORMAT_VERSION,
            BvhFileKind::Scene => SCENE_FORMAT_VERSION,
        }
    }

    /// What a file of this kind holds, for messages.
    pub const fn contents(self) -> &'static str {
        match self {
            BvhFileKind::Mesh => "a single mesh",
            BvhFileKind::Scene => "a scene",
        }
    }
}

/// The payload's sections, their names in errors and their sizes in bytes.
pub(super) fn sections(h: &Header) -> [(&'static str, Option<u64>); 5] {
    let times = |count: u64, size: u64| count.checked_mul(size);
    [
        (
            "settings",
            Some(u64::from(h.settings_len).next_multiple_of(4)),
        ),
        ("positions", times(h.vertices, 12)),
        ("triangles", times(h.triangles, 12)),
        ("nodes", times(h.nodes, NODE_SIZE as u64)),
        ("leaf entries", times(h.leaf_entries, 4)),
    ]
}

impl Header {
    /// The 64 header bytes, checksum included.
    pub fn to_bytes(self) -> [u8; HEADER_SIZE] {
        let mut b = [0u8; HEADER_SIZE];
        write_preamble(&mut b, BvhFileKind::Mesh);
        b[20..24].copy_from_slice(&self.settings_len.to_le_bytes());
        b[24..32].copy_from_slice(&self.vertices.to_le_bytes());
        b[32..40].copy_from_slice(&self.triangles.to_le_bytes());
        b[40..48].copy_from_slice(&self.nodes.to_le_bytes());
        b[48..56].copy_from_slice(&self.leaf_entries.to_le_bytes());
        b[56..60].copy_from_slice(&self.payload_crc.to_le_bytes());
        seal_header(&mut b);
        b
    }
}

/// Writes the fields every `.hbv` header starts with: magic, version, byte order, header size.
pub(super) fn write_preamble(header: &mut [u8; HEADER_SIZE], kind: BvhFileKind) {
    header[0..8].copy_from_slice(&MAGIC);
    header[8..12].copy_from_slice(&kind.version().to_le_bytes());
    header[12..16].copy_from_slice(&BYTE_ORDER_MARK.to_le_bytes());
    header[16..20].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
}

/// Writes the header's own CRC-32 (of bytes 0..60) into its last 4 bytes.
pub(super) fn seal_header(header: &mut [u8; HEADER_SIZE]) {
    let crc = crc32fast::hash(&header[0..60]);
    header[60..64].copy_from_slice(&crc.to_le_bytes());
}

/// Checks what every `.hbv` header starts with, in the order that gives the most useful
/// message: the magic number, a whole header, a known version (which tells the kind), the
/// byte order, the header's CRC-32 and its size. Returns the kind the version says.
pub(super) fn check_preamble(bytes: &[u8]) -> Result<BvhFileKind, BvhFileProblem> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(BvhFileProblem::NotBvhFile);
    }
    if bytes.len() < HEADER_SIZE {
        return Err(BvhFileProblem::Truncated {
            section: "header",
            needed: HEADER_SIZE as u64,
            len: bytes.len() as u64,
        });
    }
    let kind = match u32_at(bytes, 8) {
        MESH_FORMAT_VERSION => BvhFileKind::Mesh,
        SCENE_FORMAT_VERSION => BvhFileKind::Scene,
        found => {
            return Err(BvhFileProblem::UnsupportedVersion {
                found,
                supported: FORMAT_VERSION,
            })
        }
    };
    let mark = u32_at(bytes, 12);
    if mark != BYTE_ORDER_MARK {
        return Err(BvhFileProblem::ByteOrder { found: mark });
    }
    let (stored, computed) = (u32_at(bytes, 60), crc32fast::hash(&bytes[..60]));
    if stored != computed {
        return Err(BvhFileProblem::Checksum {
            part: "header",
            stored,
            computed,
        });
    }
    if u32_at(bytes, 16) as usize != HEADER_SIZE {
        return Err(BvhFileProblem::Invalid {
            place: "header".into(),
            reason: "header size is not 64".into(),
        });
    }
    Ok(kind)
}

/// [`check_preamble`], and a file of the `expected` kind.
pub(super) fn check_kind(bytes: &[u8], expected: BvhFileKind) -> Result<(), BvhFileProblem> {
    match check_preamble(bytes)? {
        found if found == expected => Ok(()),
        found => Err(BvhFileProblem::WrongKind { found, expected }),
    }
}

/// The end of each section in turn, from `start`, checked against `len` (the bytes there are):
/// a section past the end is [`BvhFileProblem::Truncated`], sizes that overflow
/// [`BvhFileProblem::ImpossibleSize`]. Returns the end of the last; nothing is allocated.
pub(super) fn check_section_ends(
    start: u64,
    sections: impl IntoIterator<Item = (&'static str, Option<u64>)>,
    len: u64,
) -> Result<u64, BvhFileProblem> {
    let mut end = start;
    for (section, size) in sections {
        end = size
            .and_then(|s| end.checked_add(s))
            .ok_or(BvhFileProblem::ImpossibleSize { section })?;
        if end > len {
            return Err(BvhFileProblem::Truncated {
                section,
                needed: end,
                len,
            });
        }
    }
    Ok(end)
}

/// Little-endian `u32` at `at` (the caller has checked the length).
pub(super) fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

/// Little-endian `u64` at `at` (the caller has checked the length).
pub(super) fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}
