//! Reading and checking `.hbv` files.

use std::path::Path;

use glam::Vec3;

use super::error::{BvhFileError, BvhFileProblem};
use super::format::{
    check_kind, check_section_ends, sections, u32_at, u64_at, BvhFileKind, Header, HEADER_SIZE,
    LEAF_BIT, MAX_SETTINGS, NODE_SIZE,
};
use super::BvhFile;
use crate::bvh::build::primitive_bounds;
use crate::bvh::{BuildTree, NodeId};
use crate::geometry::Aabb;
use crate::mesh::{refuse_devices, TriangleMesh};

/// Reads the whole file, then parses it.
///
/// The file is read into memory, not memory-mapped: a mapped file that another process
/// truncates or rewrites while it loads kills this one with SIGBUS (27 of 40 loads of a 50 MB
/// file rewritten in place during the load). A read cannot fault: a file that shrank meanwhile
/// reads short and is reported truncated, one rewritten meanwhile fails its CRC-32. Reading
/// costs no more than mapping here (the parser reads every byte for the CRC-32 and copies the
/// tree out either way; BENCHMARKS.md, "Loading a saved tree").
pub(super) fn load(path: &Path) -> Result<BvhFile, BvhFileError> {
    parse(&read_file(path)?, path)
}

/// The bytes of the `.hbv` file at `path`, read whole; devices and sockets refused.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, BvhFileError> {
    let fail = |e| BvhFileError {
        path: path.into(),
        problem: BvhFileProblem::Io(e),
    };
    // `/dev/zero` named `x.hbv` would otherwise be read for ever.
    refuse_devices(path, "a .hbv file").map_err(fail)?;
    std::fs::read(path).map_err(fail)
}

pub(super) fn parse(bytes: &[u8], path: &Path) -> Result<BvhFile, BvhFileError> {
    parse_checked(bytes).map_err(|problem| BvhFileError {
        path: path.into(),
        problem,
    })
}

pub(super) fn invalid(place: impl Into<String>, reason: impl Into<String>) -> BvhFileProblem {
    BvhFileProblem::Invalid {
        place: place.into(),
        reason: reason.into(),
    }
}

/// The header of a mesh file, checked ([`check_kind`]), and the end of its last section, checked
/// against the bytes there are (so nothing is allocated for sizes the file does not have).
fn read_header(bytes: &[u8]) -> Result<(Header, u64), BvhFileProblem> {
    check_kind(bytes, BvhFileKind::Mesh)?;
    let header = Header {
        settings_len: u32_at(bytes, 20),
        vertices: u64_at(bytes, 24),
        triangles: u64_at(bytes, 32),
        nodes: u64_at(bytes, 40),
        leaf_entries: u64_at(bytes, 48),
        payload_crc: u32_at(bytes, 56),
    };
    if header.settings_len > MAX_SETTINGS {
        return Err(BvhFileProblem::ImpossibleSize {
            section: "settings",
        });
    }
    let end = check_section_ends(HEADER_SIZE as u64, sections(&header), bytes.len() as u64)?;
    Ok((header, end))
}

/// The mesh file that starts `bytes` (a scene file's mesh section), and where it ends: what
/// follows it is not its concern.
pub(super) fn parse_leading(bytes: &[u8]) -> Result<(BvhFile, usize), BvhFileProblem> {
    let (_, end) = read_header(bytes)?;
    // `end` is at most `bytes.len()`, checked by `read_header`.
    let end = end as usize;
    Ok((parse_checked(&bytes[..end])?, end))
}

fn parse_checked(bytes: &[u8]) -> Result<BvhFile, BvhFileProblem> {
    let (header, end) = read_header(bytes)?;
    let len = bytes.len() as u64;
    if end < len {
        return Err(BvhFileProblem::TrailingBytes { expected: end, len });
    }
    let payload = &bytes[HEADER_SIZE..];
    let computed = crc32fast::hash(payload);
    if computed != header.payload_crc {
        return Err(BvhFileProblem::Checksum {
            part: "payload",
            stored: header.payload_crc,
            computed,
        });
    }
    // The sizes were checked against the length, so the sections below are all in `bytes`
    // and every count fits in memory as far as the file does.
    let mut at = 0usize;
    let mut section = |size: Option<u64>| {
        let size = size.expect("checked by read_header") as usize;
        let s = &payload[at..at + size];
        at += size;
        s
    };
    let [settings, positions, triangles, nodes, entries] = sections(&header).map(|s| s.1);
    let settings = section(settings);
    let settings = std::str::from_utf8(&settings[..header.settings_len as usize])
        .map_err(|e| invalid("settings", format!("not UTF-8: {e}")))?
        .to_string();
    let floats = |b: &[u8]| -> Vec<f32> {
        b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect()
    };
    let words = |b: &[u8]| -> Vec<u32> {
        b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect()
    };
    let positions: Vec<Vec3> = floats(section(positions))
        .chunks_exact(3)
        .map(Vec3::from_slice)
        .collect();
    let indices: Vec<[u32; 3]> = words(section(triangles))
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let mesh = TriangleMesh::new(positions, indices).map_err(|e| invalid("mesh", e.to_string()))?;
    let nodes = section(nodes);
    let entries = words(section(entries));
    let tree = read_tree(nodes, &entries, &mesh)?;
    Ok(BvhFile {
        mesh,
        tree,
        settings,
    })
}

/// A stored node: its box, and its child range or (leaf) entry range.
struct StoredNode {
    bounds: Aabb,
    first: usize,
    count: usize,
    is_leaf: bool,
}

fn stored_node(record: &[u8]) -> StoredNode {
    let f = |k: usize| f32::from_le_bytes(record[4 * k..4 * k + 4].try_into().expect("4 bytes"));
    let count = u32_at(record, 28);
    StoredNode {
        bounds: Aabb::new(Vec3::new(f(0), f(1), f(2)), Vec3::new(f(3), f(4), f(5))),
        first: u32_at(record, 24) as usize,
        count: (count & !LEAF_BIT) as usize,
        is_leaf: count & LEAF_BIT != 0,
    }
}

/// Rebuilds the tree from its stored nodes, checking that they form one tree over the mesh's
/// triangles whose boxes hold what is below them ([`BuildTree::validate`]).
fn read_tree(
    nodes: &[u8],
    entries: &[u32],
    mesh: &TriangleMesh,
) -> Result<BuildTree, BvhFileProblem> {
    let stored: Vec<StoredNode> = nodes.chunks_exact(NODE_SIZE).map(stored_node).collect();
    let n = stored.len();
    let mut tree = BuildTree::with_capacity(n);
    if n == 0 {
        if !entries.is_empty() {
            return Err(invalid("leaf entries", "present in a file without nodes"));
        }
        return Ok(tree);
    }
    // Children come after their parent and each node but the root is some node's child: the
    // nodes then form one tree (no cycle, nothing shared, nothing left over).
    let mut has_parent = vec![false; n];
    let mut entry_used = vec![false; entries.len()];
    let mut max_leaf = 1;
    for (i, node) in stored.iter().enumerate() {
        let place = || format!("node {i}");
        let end = node.first.checked_add(node.count);
        if node.count == 0 {
            return Err(invalid(place(), "is empty"));
        }
        if node.is_leaf {
            let end = end.filter(|&e| e <= entries.len()).ok_or_else(|| {
                invalid(
                    place(),
                    "its triangles lie past the end of the leaf entries",
                )
            })?;
            for k in node.first..end {
                if std::mem::replace(&mut entry_used[k], true) {
                    return Err(invalid(place(), format!("leaf entry {k} is used twice")));
                }
                if entries[k] as usize >= mesh.triangle_count() {
                    return Err(invalid(
                        place(),
                        format!(
                            "triangle {} is out of range (the mesh has {})",
                            entries[k],
                            mesh.triangle_count()
                        ),
                    ));
                }
            }
            max_leaf = max_leaf.max(node.count);
        } else {
            let end = end
                .filter(|&e| e <= n)
                .ok_or_else(|| invalid(place(), "its children lie past the end of the nodes"))?;
            if node.first <= i {
                return Err(invalid(place(), "a child does not come after its parent"));
            }
            for (c, seen) in has_parent.iter_mut().enumerate().take(end).skip(node.first) {
                if std::mem::replace(seen, true) {
                    return Err(invalid(place(), format!("child {c} has two parents")));
                }
            }
        }
    }
    if let Some(orphan) = (1..n).find(|&i| !has_parent[i]) {
        return Err(invalid(format!("node {orphan}"), "is not in the tree"));
    }
    if let Some(k) = entry_used.iter().position(|&u| !u) {
        return Err(invalid(format!("leaf entry {k}"), "belongs to no leaf"));
    }
    // Built bottom-up: children have larger indices.
    let mut id_of: Vec<NodeId> = vec![0; n];
    for i in (0..n).rev() {
        let node = &stored[i];
        let id = if node.is_leaf {
            tree.push_leaf(&entries[node.first..node.first + node.count], node.bounds)
        } else {
            let id = tree.push_internal(&id_of[node.first..node.first + node.count]);
            tree.node_mut(id).bounds = node.bounds;
            id
        };
        id_of[i] = id;
    }
    tree.set_root(Some(id_of[0]));
    tree.validate(&primitive_bounds(mesh), max_leaf)
        .map_err(|e| invalid("tree", e.to_string()))?;
    Ok(tree)
}
