//! Writing `.hbv` files.

use std::collections::VecDeque;
use std::io::{self, BufWriter, Write};

use super::format::{Header, LEAF_BIT, MAX_SETTINGS, NODE_SIZE};
use super::BvhFile;
use crate::bvh::{BuildTree, NodeContent, NodeId};
use crate::mesh::TriangleMesh;

/// One node as stored: its tree node, and where its children or triangles start in the file.
struct StoredNode {
    id: NodeId,
    first: u32,
}

/// The tree's nodes in breadth-first order, each node's children side by side (so an internal
/// node's children are one range, after it), with where each child range and each leaf's
/// entries start; and the number of leaf entries.
fn breadth_first(tree: &BuildTree) -> (Vec<StoredNode>, u64) {
    let mut order = Vec::new();
    let mut entries = 0u64;
    let mut queue: VecDeque<NodeId> = tree.root().into_iter().collect();
    let mut next_index = queue.len() as u32;
    while let Some(id) = queue.pop_front() {
        let first = match &tree.node(id).content {
            NodeContent::Internal(children) => {
                queue.extend(children);
                let first = next_index;
                next_index += children.len() as u32;
                first
            }
            NodeContent::Leaf(prims) => {
                let first = entries as u32;
                entries += prims.len() as u64;
                first
            }
        };
        order.push(StoredNode { id, first });
    }
    (order, entries)
}

/// One mesh file's contents, borrowed: what [`BvhFile`] holds, or a scene's mesh and its tree.
#[derive(Clone, Copy)]
pub(super) struct MeshParts<'a> {
    pub mesh: &'a TriangleMesh,
    pub tree: &'a BuildTree,
    pub settings: &'a str,
}

impl<'a> From<&'a BvhFile> for MeshParts<'a> {
    fn from(file: &'a BvhFile) -> Self {
        MeshParts {
            mesh: &file.mesh,
            tree: &file.tree,
            settings: &file.settings,
        }
    }
}

/// Writes a mesh file of `parts` to `out`: the payload is produced twice, once into the
/// checksum and once into the file, so that nothing as large as the mesh is buffered.
pub(super) fn write(parts: MeshParts<'_>, out: &mut impl Write) -> io::Result<()> {
    let settings = truncated_settings(parts.settings);
    let (order, leaf_entries) = breadth_first(parts.tree);
    let mut crc = BufWriter::with_capacity(1 << 16, CrcSink::default());
    write_payload(parts, settings, &order, &mut crc)?;
    let crc = crc.into_inner().map_err(|e| e.into_error())?;
    let header = Header {
        settings_len: settings.len() as u32,
        vertices: parts.mesh.positions().len() as u64,
        triangles: parts.mesh.triangle_count() as u64,
        nodes: order.len() as u64,
        leaf_entries,
        payload_crc: crc.finalize(),
    };
    let mut out = BufWriter::with_capacity(1 << 20, out);
    out.write_all(&header.to_bytes())?;
    write_payload(parts, settings, &order, &mut out)?;
    out.flush()
}

/// Passes writes through to `out`, counting the bytes: the size of a saved file, told without
/// asking the file system (a pipe has none).
pub(super) struct CountedWriter<W> {
    out: W,
    bytes: u64,
}

impl<W: Write> CountedWriter<W> {
    pub(super) fn new(out: W) -> Self {
        CountedWriter { out, bytes: 0 }
    }

    pub(super) fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl<W: Write> Write for CountedWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.out.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// The settings line, cut at a character boundary to at most [`MAX_SETTINGS`] bytes.
fn truncated_settings(settings: &str) -> &str {
    let mut end = settings.len().min(MAX_SETTINGS as usize);
    while !settings.is_char_boundary(end) {
        end -= 1;
    }
    &settings[..end]
}

fn write_payload(
    parts: MeshParts<'_>,
    settings: &str,
    order: &[StoredNode],
    out: &mut impl Write,
) -> io::Result<()> {
    out.write_all(settings.as_bytes())?;
    out.write_all(&[0u8; 3][..settings.len().next_multiple_of(4) - settings.len()])?;
    for p in parts.mesh.positions() {
        for c in p.to_array() {
            out.write_all(&c.to_le_bytes())?;
        }
    }
    for tri in parts.mesh.indices() {
        for i in tri {
            out.write_all(&i.to_le_bytes())?;
        }
    }
    let tree = parts.tree;
    for stored in order {
        let node = tree.node(stored.id);
        let mut record = [0u8; NODE_SIZE];
        let corners = node.bounds.min.to_array().into_iter();
        for (k, c) in corners.chain(node.bounds.max.to_array()).enumerate() {
            record[4 * k..4 * k + 4].copy_from_slice(&c.to_le_bytes());
        }
        let count = match &node.content {
            NodeContent::Internal(children) => children.len() as u32,
            NodeContent::Leaf(prims) => prims.len() as u32 | LEAF_BIT,
        };
        record[24..28].copy_from_slice(&stored.first.to_le_bytes());
        record[28..32].copy_from_slice(&count.to_le_bytes());
        out.write_all(&record)?;
    }
    for stored in order {
        for p in tree.node(stored.id).prims() {
            out.write_all(&p.to_le_bytes())?;
        }
    }
    Ok(())
}

/// A writer that only feeds a checksum.
#[derive(Default)]
pub(super) struct CrcSink(crc32fast::Hasher);

impl CrcSink {
    /// The CRC-32 of everything written.
    pub(super) fn finalize(self) -> u32 {
        self.0.finalize()
    }
}

impl Write for CrcSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.update(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
