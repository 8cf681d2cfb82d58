//! Meshes whose vertices move: the mesh's tree is refitted through the dynamic tree
//! ([`DynamicBvh`]), laid out again, and every instance of the mesh moves with it.
//!
//! A refit keeps the topology the mesh was built with (Wald, Boulos & Shirley 2007 refit
//! animated scenes this way): cheap, and as good as a rebuild while the vertices move
//! coherently (a mesh that breathes, bends or walks). A mesh torn apart or shuffled traces
//! slower after each refit; add it again ([`Scene::add_mesh`]) to build it anew.
//!
//! The layout is made again either way, and it is most of the time: on the 69,696-triangle
//! torus of `examples/scene_update.rs` a move of its vertices takes 21 ms (44 ms the first
//! time, which also builds the tree kept for the next refits) where building and laying it out
//! takes 29 ms. Refitting the layout in place would make this cheap; it is not done yet.

use glam::Vec3;

use super::instance::InstanceState;
use super::{MeshId, Scene, SceneError};
use crate::bvh::dynamic::{DynamicBvh, DynamicConfig};
use crate::mesh::{TriangleMesh, MAX_COORDINATE};

impl Scene {
    /// Moves the vertices of mesh `mesh` to `positions` (one for each vertex, in order; the
    /// faces stay). The mesh's tree is refitted: the tree is taken over by a [`DynamicBvh`],
    /// each face set to its new triangle, the boxes refitted bottom-up, and the result laid out
    /// as the scene lays out its meshes. Every instance of the mesh gets its new world box and
    /// is tested in turn until the next [`Scene::update`], as a moved instance is.
    ///
    /// Refused, the scene unchanged, for an unknown mesh, a count of positions other than the
    /// mesh's, or a coordinate that is not finite or beyond `±MAX_COORDINATE`. After the first
    /// call the mesh keeps its tree beside its layout (for the next refit).
    pub fn set_mesh_positions(
        &mut self,
        mesh: MeshId,
        positions: Vec<Vec3>,
    ) -> Result<(), SceneError> {
        let meshes = self.meshes.len();
        let Some(scene_mesh) = self.meshes.get_mut(mesh.0 as usize) else {
            return Err(SceneError::UnknownMesh { mesh, meshes });
        };
        let expected = scene_mesh.mesh.positions().len();
        if positions.len() != expected {
            return Err(SceneError::PositionCount {
                mesh,
                expected,
                given: positions.len(),
            });
        }
        if let Some(vertex) = positions
            .iter()
            .position(|p| !p.is_finite() || p.abs().max_element() > MAX_COORDINATE)
        {
            return Err(SceneError::InvalidPosition { mesh, vertex });
        }
        let moved = TriangleMesh::new(positions, scene_mesh.mesh.indices().to_vec())
            .expect("the faces are the mesh's and every position was checked");
        let s = &self.structure;
        let tree = scene_mesh
            .tree
            .take()
            .unwrap_or_else(|| s.builder.build(&scene_mesh.mesh, &s.builder_options));
        let mut dynamic = DynamicBvh::from_tree(&scene_mesh.mesh, tree, DynamicConfig::default());
        for (face, triangle) in moved.triangles().enumerate() {
            dynamic
                .set_triangle(face as u32, [triangle.p0, triangle.p1, triangle.p2])
                .expect("every face of the mesh has its id in the tree, and is finite");
        }
        dynamic.refit();
        let tree = dynamic.tree().clone();
        scene_mesh.layout = s.layout.lay_out(&tree, &moved, &s.layout_options);
        scene_mesh.bounds = moved.bounds();
        scene_mesh.mesh = moved;
        scene_mesh.tree = Some(tree);
        scene_mesh.search = std::sync::OnceLock::new();
        for index in 0..self.instances.len() {
            let instance = self.instances[index];
            if instance.mesh == mesh.0 && instance.state != InstanceState::Removed {
                self.place_instance(index, instance.transform);
            }
        }
        Ok(())
    }
}
