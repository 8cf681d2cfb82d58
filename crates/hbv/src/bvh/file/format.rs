//! The byte layout of `.hbv` files, version 1. Everything is little-endian.
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

/// The first 8 bytes of every `.hbv` file.
pub const MAGIC: [u8; 8] = *b"\x89HBV\r\n\x1a\n";
/// The version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
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
        b[0..8].copy_from_slice(&MAGIC);
        b[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        b[12..16].copy_from_slice(&BYTE_ORDER_MARK.to_le_bytes());
        b[16..20].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
        b[20..24].copy_from_slice(&self.settings_len.to_le_bytes());
        b[24..32].copy_from_slice(&self.vertices.to_le_bytes());
        b[32..40].copy_from_slice(&self.triangles.to_le_bytes());
        b[40..48].copy_from_slice(&self.nodes.to_le_bytes());
        b[48..56].copy_from_slice(&self.leaf_entries.to_le_bytes());
        b[56..60].copy_from_slice(&self.payload_crc.to_le_bytes());
        let crc = crc32fast::hash(&b[0..60]);
        b[60..64].copy_from_slice(&crc.to_le_bytes());
        b
    }
}

/// Little-endian `u32` at `at` (the caller has checked the length).
pub(super) fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

/// Little-endian `u64` at `at` (the caller has checked the length).
pub(super) fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}
