//! The wide layout's invariants, checked: what the tests ask of every way of making one.

use super::node::{is_leaf, leaf_span};
use super::WideLayout;
use crate::bvh::InvariantError;
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;

impl<const W: usize> WideLayout<W> {
    /// Checks the layout against `mesh`, the mesh it was made over:
    /// - every non-degenerate triangle is in exactly one leaf, with its vertices as the mesh
    ///   has them, and no degenerate triangle is in any;
    /// - every lane's box contains its child: a node's boxes, or a leaf's triangles; the root's
    ///   box contains the root's;
    /// - every node is reached once, and every lane with a child has a non-empty box.
    pub fn validate(&self, mesh: &TriangleMesh) -> Result<(), InvariantError> {
        let fail = |s: String| Err(InvariantError(s));
        let mut seen = vec![false; mesh.triangle_count()];
        let mut reached = vec![false; self.nodes.len()];
        let mut stack = Vec::new();
        if let Some((root, bounds, _)) = self.root {
            stack.push((root, bounds));
        }
        while let Some((reference, bounds)) = stack.pop() {
            if is_leaf(reference) {
                let (first, count) = leaf_span(reference);
                let Some(packets) = self.packets.get(first..first + count) else {
                    return fail(format!("leaf {reference:#x} is past the packets"));
                };
                for packet in packets {
                    for lane in 0..4 {
                        if packet.repeats_previous(lane) {
                            continue;
                        }
                        let id = packet.ids[lane] as usize;
                        let triangle = packet.triangle(lane);
                        if id >= mesh.triangle_count() || triangle != mesh.triangle(id) {
                            return fail(format!(
                                "leaf {reference:#x} holds a triangle {id} the mesh has not"
                            ));
                        }
                        if triangle.is_degenerate() {
                            return fail(format!("degenerate triangle {id} is in a leaf"));
                        }
                        if std::mem::replace(&mut seen[id], true) {
                            return fail(format!("triangle {id} is in two leaves"));
                        }
                        if !bounds.contains(&triangle.bounds()) {
                            return fail(format!(
                                "the box of leaf {reference:#x} does not contain triangle {id}"
                            ));
                        }
                    }
                }
                continue;
            }
            let Some(node) = self.nodes.get(reference as usize) else {
                return fail(format!("node {reference} is past the nodes"));
            };
            if std::mem::replace(&mut reached[reference as usize], true) {
                return fail(format!("node {reference} is reached twice"));
            }
            let mut children = 0;
            for lane in 0..W {
                let lane_box = Aabb::new(
                    std::array::from_fn::<f32, 3, _>(|axis| node.boxes[0][axis][lane]).into(),
                    std::array::from_fn::<f32, 3, _>(|axis| node.boxes[1][axis][lane]).into(),
                );
                if lane_box.is_empty() {
                    continue;
                }
                if !bounds.contains(&lane_box) {
                    return fail(format!(
                        "node {reference} lane {lane} is outside its parent's box"
                    ));
                }
                children += 1;
                stack.push((node.children[lane], lane_box));
            }
            if children == 0 {
                return fail(format!("node {reference} has no children"));
            }
        }
        if let Some(id) = (0..seen.len()).find(|&i| !seen[i] && !mesh.triangle(i).is_degenerate()) {
            return fail(format!("triangle {id} is in no leaf"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::BinnedSahConfig;
    use crate::mesh::procedural::torus;
    use glam::Vec3;

    #[test]
    fn broken_layouts_are_found() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.6, 24, 12);
        let layout = WideLayout::<8>::build_direct(&mesh, &BinnedSahConfig::default());
        layout.validate(&mesh).unwrap();

        let mut twice = layout.clone();
        twice.packets[1].ids[0] = twice.packets[0].ids[0];
        twice.packets[1].vertices = twice.packets[0].vertices;
        assert!(twice.validate(&mesh).is_err());

        // A triangle's copy in a lane of its own (not padding) within its leaf.
        let mut copied = layout.clone();
        let lanes = (0..4).find(|&k| k > 1 && !copied.packets[0].repeats_previous(k));
        if let Some(k) = lanes {
            let packet = &mut copied.packets[0];
            packet.ids[k] = packet.ids[0];
            for v in 0..3 {
                for axis in 0..3 {
                    packet.vertices[v][axis][k] = packet.vertices[v][axis][0];
                }
            }
            let error = copied.validate(&mesh).unwrap_err().0;
            assert!(error.contains("in two leaves"), "{error}");
        }

        let mut moved = layout.clone();
        moved.packets[0].vertices[0][0][0] += 1.0;
        assert!(moved.validate(&mesh).is_err());

        let mut shrunk = layout.clone();
        let root = shrunk.root.unwrap().0 as usize;
        shrunk.nodes[root].boxes[1][0][0] = shrunk.nodes[root].boxes[0][0][0];
        assert!(shrunk.validate(&mesh).is_err());

        let other = torus(Vec3::ZERO, 2.0, 0.6, 24, 13);
        assert!(layout.validate(&other).is_err());
    }
}
