//! A leaf's triangles packed in fours: how every wide layout writes its leaves, whether laid
//! out from a build tree or built directly.

use super::node::leaf_reference;
use super::TrianglePacket;
use crate::mesh::TriangleMesh;

/// Packs the triangles `prims` of `mesh` (1 to [`MAX_LEAF_TRIANGLES`](super::node::MAX_LEAF_TRIANGLES))
/// into triangle packets at the end of `packets`, four a packet in the order given (the last
/// packet repeats its last triangle in spare lanes), and returns the leaf's reference.
pub(super) fn push_leaf_packets(
    packets: &mut Vec<TrianglePacket>,
    mesh: &TriangleMesh,
    prims: &[u32],
) -> u32 {
    let first = packets.len() as u32;
    for chunk in prims.chunks(4) {
        let triangles: [(u32, crate::geometry::Triangle); 4] = std::array::from_fn(|k| {
            let p = chunk[k.min(chunk.len() - 1)];
            (p, mesh.triangle(p as usize))
        });
        packets.push(TrianglePacket::new(&triangles[..chunk.len()]));
    }
    leaf_reference(first, prims.len().div_ceil(4) as u32)
}
