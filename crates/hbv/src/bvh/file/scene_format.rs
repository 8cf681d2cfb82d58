//! The byte layout of `.hbv` scene files, version 2. Everything is little-endian.
//!
//! ```text
//! offset size  header (64 bytes)
//!      0    8  magic, as in version 1
//!      8    4  u32 format version (2)
//!     12    4  u32 byte-order mark 0x01020304
//!     16    4  u32 header size (64)
//!     20    4  u32 reserved, 0
//!     24    8  u64 mesh count M
//!     32    8  u64 instance count I
//!     40   16  reserved, 0
//!     56    4  u32 CRC-32 of the record section (bytes 64 .. 96 + 24 M + 112 I)
//!     60    4  u32 CRC-32 of header bytes 0..60
//! then, in this order:
//!   structure  32 bytes: how the scene builds and lays out its meshes (below)
//!   origins    M × 3 f64: where each mesh's stored vertices have their origin, in the
//!              coordinates it was given in (0 but for float64 meshes, stored relative to
//!              their centre); mesh id = index
//!   instances  I × 112 bytes, instance id = index (below)
//!   meshes     M version-1 mesh files back to back, mesh id = index, each self-delimiting
//!              (its header's sizes) and sealed by its own two CRC-32s
//!
//! structure record                          instance record
//!    0  4  u32 builder code                   0  4  u32 mesh id (< M)
//!    4  4  u32 layout code                    4  4  u32 mask
//!    8  4  u32 insertion order code           8  4  u32 state: 0 live, 1 removed
//!   12  4  u32 flags: bit 0 optimize,        12  4  u32 reserved, 0
//!                     bit 1 ray packets      16 96  12 × f64: the rows of [A | b], placing
//!   16  8  u64 leaf size, 0 = default                 the stored vertices: world = A · v + b
//!   24  8  u64 shuffle seed (0 unless shuffle)
//! ```
//!
//! Codes: builders 1 insertion, 2 binned-sah, 3 sweep-sah, 4 median, 5 lbvh, 6 ploc; layouts
//! 1 recursive, 2 skip, 3 ordered, 4 wide4, 5 wide8; insertion orders 0 input, 1 shuffle,
//! 2 morton. Codes are the file's own, not the enums' order, so that reordering an enum never
//! changes the meaning of a saved file.

use crate::bvh::build::{BuilderKind, BuilderOptions, InsertionOrder};
use crate::bvh::layout::{LayoutKind, LayoutOptions};

use super::error::BvhFileProblem;
use super::format::{seal_header, u32_at, u64_at, write_preamble, BvhFileKind, HEADER_SIZE};
use super::read::invalid;

pub(super) const STRUCTURE_SIZE: usize = 32;
pub(super) const INSTANCE_SIZE: usize = 112;
pub(super) const ORIGIN_SIZE: usize = 24;

const OPTIMIZE_FLAG: u32 = 1;
const RAY_PACKETS_FLAG: u32 = 2;

const BUILDER_CODES: [(BuilderKind, u32); 6] = [
    (BuilderKind::Insertion, 1),
    (BuilderKind::BinnedSah, 2),
    (BuilderKind::SweepSah, 3),
    (BuilderKind::Median, 4),
    (BuilderKind::Lbvh, 5),
    (BuilderKind::Ploc, 6),
];

const LAYOUT_CODES: [(LayoutKind, u32); 5] = [
    (LayoutKind::Recursive, 1),
    (LayoutKind::Skip, 2),
    (LayoutKind::Ordered, 3),
    (LayoutKind::Wide4, 4),
    (LayoutKind::Wide8, 5),
];

/// How a scene builds and lays out its meshes, as its file records it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct StoredStructure {
    pub builder: BuilderKind,
    pub builder_options: BuilderOptions,
    pub layout: LayoutKind,
    pub layout_options: LayoutOptions,
}

/// Where mesh `id`'s stored vertices have their origin: three finite f64.
pub(super) fn origin_from_bytes(b: &[u8], id: usize) -> Result<[f64; 3], BvhFileProblem> {
    let origin: [f64; 3] = std::array::from_fn(|k| f64_at(b, 8 * k));
    if origin.iter().any(|c| !c.is_finite()) {
        return Err(invalid(
            format!("mesh {id}"),
            format!("its origin {origin:?} is not finite"),
        ));
    }
    Ok(origin)
}

pub(super) fn origin_to_bytes(origin: [f64; 3]) -> [u8; ORIGIN_SIZE] {
    let mut b = [0u8; ORIGIN_SIZE];
    for (k, c) in origin.iter().enumerate() {
        b[8 * k..8 * k + 8].copy_from_slice(&c.to_le_bytes());
    }
    b
}

/// Little-endian `f64` at `at` (the caller has checked the length).
fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// An instance as its file records it; the transform is checked by the scene that reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StoredInstance {
    pub mesh: u32,
    pub mask: u32,
    pub removed: bool,
    /// The rows of `[A | b]`.
    pub rows: [[f64; 4]; 3],
}

/// The header's own fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct SceneHeader {
    pub meshes: u64,
    pub instances: u64,
    pub records_crc: u32,
}

impl SceneHeader {
    /// The 64 header bytes, checksum included.
    pub fn to_bytes(self) -> [u8; HEADER_SIZE] {
        let mut b = [0u8; HEADER_SIZE];
        write_preamble(&mut b, BvhFileKind::Scene);
        b[24..32].copy_from_slice(&self.meshes.to_le_bytes());
        b[32..40].copy_from_slice(&self.instances.to_le_bytes());
        b[56..60].copy_from_slice(&self.records_crc.to_le_bytes());
        seal_header(&mut b);
        b
    }

    /// The fields of a header whose preamble was checked: reserved bytes must be zero.
    pub fn from_bytes(b: &[u8]) -> Result<Self, BvhFileProblem> {
        if u32_at(b, 20) != 0 || b[40..56].iter().any(|&x| x != 0) {
            return Err(invalid(
                "header",
                "reserved bytes (20..24, 40..56) are not 0",
            ));
        }
        Ok(SceneHeader {
            meshes: u64_at(b, 24),
            instances: u64_at(b, 32),
            records_crc: u32_at(b, 56),
        })
    }
}

/// The code of `value` in `table`.
fn code_of<T: PartialEq + Copy>(table: &[(T, u32)], value: T) -> u32 {
    table
        .iter()
        .find(|(v, _)| *v == value)
        .map(|&(_, c)| c)
        .expect("every value has its code")
}

/// The value whose code in `table` is `code`, if any.
fn value_of<T: Copy>(table: &[(T, u32)], code: u32) -> Option<T> {
    table.iter().find(|&&(_, c)| c == code).map(|&(v, _)| v)
}

impl StoredStructure {
    pub fn to_bytes(self) -> [u8; STRUCTURE_SIZE] {
        let options = &self.builder_options;
        let (order, seed) = match options.insertion_order {
            InsertionOrder::Input => (0, 0),
            InsertionOrder::Shuffle { seed } => (1, seed),
            InsertionOrder::Morton => (2, 0),
        };
        let flags = if options.optimize { OPTIMIZE_FLAG } else { 0 }
            | if self.layout_options.ray_packets {
                RAY_PACKETS_FLAG
            } else {
                0
            };
        let mut b = [0u8; STRUCTURE_SIZE];
        b[0..4].copy_from_slice(&code_of(&BUILDER_CODES, self.builder).to_le_bytes());
        b[4..8].copy_from_slice(&code_of(&LAYOUT_CODES, self.layout).to_le_bytes());
        b[8..12].copy_from_slice(&(order as u32).to_le_bytes());
        b[12..16].copy_from_slice(&flags.to_le_bytes());
        let leaf = options.leaf_size.map_or(0, |k| k as u64);
        b[16..24].copy_from_slice(&leaf.to_le_bytes());
        b[24..32].copy_from_slice(&seed.to_le_bytes());
        b
    }

    pub fn from_bytes(b: &[u8]) -> Result<Self, BvhFileProblem> {
        let bad = |reason: String| invalid("structure", reason);
        let builder = value_of(&BUILDER_CODES, u32_at(b, 0))
            .ok_or_else(|| bad(format!("unknown builder code {}", u32_at(b, 0))))?;
        let layout = value_of(&LAYOUT_CODES, u32_at(b, 4))
            .ok_or_else(|| bad(format!("unknown layout code {}", u32_at(b, 4))))?;
        let seed = u64_at(b, 24);
        let insertion_order = match u32_at(b, 8) {
            0 => InsertionOrder::Input,
            1 => InsertionOrder::Shuffle { seed },
            2 => InsertionOrder::Morton,
            code => return Err(bad(format!("unknown insertion order code {code}"))),
        };
        if seed != 0 && !matches!(insertion_order, InsertionOrder::Shuffle { .. }) {
            return Err(bad(
                "a seed is given for an order that is not shuffled".into()
            ));
        }
        let flags = u32_at(b, 12);
        if flags & !(OPTIMIZE_FLAG | RAY_PACKETS_FLAG) != 0 {
            return Err(bad(format!("unknown flags {flags:#x}")));
        }
        let leaf_size = match u64_at(b, 16) {
            0 => None,
            k => Some(
                usize::try_from(k)
                    .ok()
                    .filter(|&k| k <= u32::MAX as usize)
                    .ok_or_else(|| bad(format!("leaf size {k} is too large")))?,
            ),
        };
        Ok(StoredStructure {
            builder,
            builder_options: BuilderOptions {
                leaf_size,
                insertion_order,
                optimize: flags & OPTIMIZE_FLAG != 0,
            },
            layout,
            layout_options: LayoutOptions {
                ray_packets: flags & RAY_PACKETS_FLAG != 0,
            },
        })
    }
}

impl StoredInstance {
    pub fn to_bytes(self) -> [u8; INSTANCE_SIZE] {
        let mut b = [0u8; INSTANCE_SIZE];
        b[0..4].copy_from_slice(&self.mesh.to_le_bytes());
        b[4..8].copy_from_slice(&self.mask.to_le_bytes());
        b[8..12].copy_from_slice(&u32::from(self.removed).to_le_bytes());
        for (k, value) in self.rows.iter().flatten().enumerate() {
            b[16 + 8 * k..24 + 8 * k].copy_from_slice(&value.to_le_bytes());
        }
        b
    }

    /// The record of instance `id`, in a scene of `meshes` meshes.
    pub fn from_bytes(b: &[u8], id: usize, meshes: u64) -> Result<Self, BvhFileProblem> {
        let bad = |reason: String| invalid(format!("instance {id}"), reason);
        let mesh = u32_at(b, 0);
        if u64::from(mesh) >= meshes {
            return Err(bad(format!(
                "mesh {mesh} is out of range (the scene has {meshes})"
            )));
        }
        let removed = match u32_at(b, 8) {
            0 => false,
            1 => true,
            state => return Err(bad(format!("unknown state {state} (0 live, 1 removed)"))),
        };
        if u32_at(b, 12) != 0 {
            return Err(bad("reserved bytes 12..16 are not 0".into()));
        }
        let entry = |k: usize| f64_at(b, 16 + 8 * k);
        Ok(StoredInstance {
            mesh,
            mask: u32_at(b, 4),
            removed,
            rows: std::array::from_fn(|i| std::array::from_fn(|j| entry(4 * i + j))),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_structure_round_trips() {
        let orders = [
            InsertionOrder::Input,
            InsertionOrder::Morton,
            InsertionOrder::Shuffle { seed: 0 },
            InsertionOrder::Shuffle { seed: u64::MAX },
        ];
        for builder in BuilderKind::ALL {
            for layout in LayoutKind::ALL {
                for (k, insertion_order) in orders.into_iter().enumerate() {
                    let stored = StoredStructure {
                        builder,
                        builder_options: BuilderOptions {
                            leaf_size: [None, Some(1), Some(255)][k % 3],
                            insertion_order,
                            optimize: k % 2 == 0,
                        },
                        layout,
                        layout_options: LayoutOptions {
                            ray_packets: k % 2 == 1,
                        },
                    };
                    let back = StoredStructure::from_bytes(&stored.to_bytes()).unwrap();
                    assert_eq!(back, stored);
                }
            }
        }
    }

    #[test]
    fn bad_codes_are_named() {
        let good = StoredStructure {
            builder: BuilderKind::BinnedSah,
            builder_options: BuilderOptions::default(),
            layout: LayoutKind::Wide8,
            layout_options: LayoutOptions::default(),
        }
        .to_bytes();
        let edit = |at: usize, value: u32, want: &str| {
            let mut b = good;
            b[at..at + 4].copy_from_slice(&value.to_le_bytes());
            let e = StoredStructure::from_bytes(&b).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        };
        edit(0, 0, "structure: unknown builder code 0");
        edit(4, 6, "unknown layout code 6");
        edit(8, 3, "unknown insertion order code 3");
        edit(12, 4, "unknown flags 0x4");
        edit(20, 1, "leaf size 4294967296 is too large");
        let mut b = good;
        b[8..12].copy_from_slice(&0u32.to_le_bytes());
        b[24] = 1;
        let e = StoredStructure::from_bytes(&b).unwrap_err().to_string();
        assert!(e.contains("not shuffled"), "{e}");
    }
}
