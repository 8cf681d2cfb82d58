//! `SceneSummary`: what a scene holds, for reports (`hbv info`): its meshes and how often each is
//! placed, its triangles as stored and as seen, the top level's cost and the memory held.

use rayon::prelude::*;

use super::instance::InstanceState;
use super::Scene;
use crate::bvh::expected_tests;

/// One mesh of a scene, as [`Scene::summary`] reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshSummary {
    pub triangles: usize,
    pub vertices: usize,
    /// Live instances that place it.
    pub instances: usize,
    /// Bytes of its positions and triangle indices.
    pub mesh_bytes: usize,
    /// Bytes of its laid-out BVH (nodes and the triangles they hold).
    pub layout_bytes: usize,
}

/// A scene's contents and sizes ([`Scene::summary`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSummary {
    /// In [`MeshId`](super::MeshId) order.
    pub meshes: Vec<MeshSummary>,
    /// Instances not removed.
    pub live_instances: usize,
    /// Instance ids handed out, removed ones included.
    pub instance_ids: usize,
    /// Triangles as stored: `Σ` over the meshes, each once however often it is placed.
    pub triangles_stored: usize,
    /// Triangles as seen: `Σ` over the live instances of their mesh's triangles (the flattened
    /// scene's face count).
    pub triangles_seen: usize,
    /// The top level's E\[X\]: `Σ_n SA(n) / SA(root)` over its nodes, the expected number of
    /// its boxes a random line through the root box meets (Goldsmith & Salmon 1987; the same
    /// figure as [`TopLevelCost::current`](super::TopLevelCost)). 0 for an empty top level.
    pub top_level_expected_tests: f32,
    /// Bytes of the meshes' positions and indices, `Σ` [`MeshSummary::mesh_bytes`].
    pub mesh_bytes: usize,
    /// Bytes of the meshes' laid-out BVHs, `Σ` [`MeshSummary::layout_bytes`].
    pub layout_bytes: usize,
    /// Bytes of the instance records (transform and inverse in f64, world box, mask), every id
    /// handed out. The top level's nodes are not counted.
    pub instance_bytes: usize,
}

impl SceneSummary {
    /// Bytes held by meshes, their BVHs and the instances (the top level's nodes not counted).
    pub fn memory_bytes(&self) -> usize {
        self.mesh_bytes + self.layout_bytes + self.instance_bytes
    }
}

impl Scene {
    /// The scene's contents and sizes: `O(meshes + instances)`, no tree is built or walked
    /// beyond the top level's cost.
    pub fn summary(&self) -> SceneSummary {
        let mut meshes: Vec<MeshSummary> = self
            .meshes
            .iter()
            .map(|m| MeshSummary {
                triangles: m.mesh.triangle_count(),
                vertices: m.mesh.positions().len(),
                instances: 0,
                mesh_bytes: std::mem::size_of_val(m.mesh.positions())
                    + std::mem::size_of_val(m.mesh.indices()),
                layout_bytes: m.layout.memory_bytes(),
            })
            .collect();
        let mut live_instances = 0;
        for instance in &self.instances {
            if instance.state != InstanceState::Removed {
                live_instances += 1;
                meshes[instance.mesh as usize].instances += 1;
            }
        }
        SceneSummary {
            live_instances,
            instance_ids: self.instances.len(),
            triangles_stored: meshes.iter().map(|m| m.triangles).sum(),
            triangles_seen: meshes.iter().map(|m| m.triangles * m.instances).sum(),
            top_level_expected_tests: self.top_level.cost(),
            mesh_bytes: meshes.iter().map(|m| m.mesh_bytes).sum(),
            layout_bytes: meshes.iter().map(|m| m.layout_bytes).sum(),
            instance_bytes: std::mem::size_of_val(self.instances.as_slice()),
            meshes,
        }
    }

    /// E\[X\] of each mesh's BVH, in [`MeshId`](super::MeshId) order: `Σ_n a_n SA(n) / SA(root)` over the tree
    /// its layout was made from ([`expected_tests`], as `hbv info` reports it for a mesh). The
    /// layouts do not keep their trees, so each is built again by the scene's builder (builds
    /// are deterministic: the same tree), in parallel on the current rayon pool; a mesh whose
    /// vertices moved answers with the tree it keeps for refitting. As costly as adding the
    /// meshes again.
    pub fn mesh_expected_tests(&self) -> Vec<f64> {
        let s = &self.structure;
        self.meshes
            .par_iter()
            .map(|m| match &m.tree {
                Some(tree) => expected_tests(tree),
                None => expected_tests(&s.builder.build(&m.mesh, &s.builder_options)),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};

    use super::*;
    use crate::bvh::build::BuilderOptions;
    use crate::mesh::procedural::{icosphere, torus};
    use crate::scene::{InstanceId, InstanceTransform, MeshId, SceneStructure};

    /// A sphere placed three times (one of them then removed), a torus once, and a mesh never
    /// placed.
    fn scene() -> Scene {
        let mut scene = Scene::new();
        let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
        let ring = scene.add_mesh(torus(Vec3::ZERO, 2.0, 0.5, 12, 8));
        scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 0));
        for x in [0.0, 4.0, 8.0] {
            let at = InstanceTransform::from_translation(DVec3::new(x, 0.0, 0.0)).unwrap();
            scene.add_instance(sphere, at, u32::MAX).unwrap();
        }
        let up = InstanceTransform::from_translation(DVec3::new(0.0, 5.0, 0.0)).unwrap();
        scene.add_instance(ring, up, u32::MAX).unwrap();
        scene.build();
        scene.remove_instance(InstanceId(1)).unwrap();
        scene
    }

    #[test]
    fn counts_meshes_instances_and_triangles_as_the_flattened_scene_does() {
        let scene = scene();
        let summary = scene.summary();
        let sphere = scene.mesh(MeshId(0)).unwrap().triangle_count();
        let ring = scene.mesh(MeshId(1)).unwrap().triangle_count();
        let unplaced = scene.mesh(MeshId(2)).unwrap().triangle_count();
        let instances: Vec<usize> = summary.meshes.iter().map(|m| m.instances).collect();
        assert_eq!(instances, [2, 1, 0]);
        assert_eq!(summary.live_instances, 3);
        assert_eq!(summary.instance_ids, 4);
        assert_eq!(summary.triangles_stored, sphere + ring + unplaced);
        assert_eq!(summary.triangles_seen, 2 * sphere + ring);
        let flat = scene.flattened().unwrap();
        assert_eq!(summary.triangles_seen, flat.mesh.triangle_count());
        assert_eq!(
            summary.top_level_expected_tests,
            scene.top_level_cost().current
        );
        assert!(summary.top_level_expected_tests >= 1.0);
        // Bytes: each part positive, and the total their sum.
        assert!(summary.mesh_bytes > 0 && summary.layout_bytes > 0);
        assert!(summary.instance_bytes > 0);
        assert_eq!(
            summary.memory_bytes(),
            summary.mesh_bytes + summary.layout_bytes + summary.instance_bytes
        );
        assert_eq!(
            summary.meshes[0].mesh_bytes,
            sphere * 12 + summary.meshes[0].vertices * 12
        );
    }

    #[test]
    fn mesh_expected_tests_are_those_of_a_tree_built_alike() {
        let structure = SceneStructure {
            builder: crate::bvh::build::BuilderKind::Insertion,
            ..SceneStructure::default()
        };
        let mut scene = Scene::with_structure(structure);
        let meshes = [
            icosphere(Vec3::ZERO, 1.0, 3),
            torus(Vec3::ZERO, 2.0, 0.5, 16, 8),
        ];
        for mesh in &meshes {
            scene.add_mesh(mesh.clone());
        }
        let costs = scene.mesh_expected_tests();
        for (mesh, cost) in meshes.iter().zip(costs) {
            let tree = structure.builder.build(mesh, &BuilderOptions::default());
            assert_eq!(cost, expected_tests(&tree));
            assert!(cost > 1.0);
        }
    }

    #[test]
    fn an_empty_scene_sums_to_nothing() {
        let mut scene = Scene::new();
        scene.build();
        let summary = scene.summary();
        assert!(summary.meshes.is_empty());
        assert_eq!(summary.live_instances, 0);
        assert_eq!(summary.triangles_seen, 0);
        assert_eq!(summary.top_level_expected_tests, 0.0);
        assert_eq!(summary.memory_bytes(), 0);
        assert!(scene.mesh_expected_tests().is_empty());
    }
}
