//! The scene as hbv's two-level [`hbv::scene::Scene`]: each mesh's BVH built once, a top-level
//! BVH over the instances.

use hbv::scene::{MeshId, SceneStructure};

use super::Scene;

impl Scene {
    /// The two-level scene: every mesh added once (built and laid out as `structure` says),
    /// every instance placed by its transform with every mask bit set, in order, so that the
    /// library's instance ids are this scene's; the top level built.
    pub fn two_level(&self, structure: SceneStructure) -> hbv::scene::Scene {
        let mut scene = hbv::scene::Scene::with_structure(structure);
        for mesh in &self.meshes {
            scene.add_mesh(mesh.mesh.clone());
        }
        for instance in &self.instances {
            scene
                .add_instance(MeshId(instance.mesh), instance.transform, u32::MAX)
                .expect("instances place meshes of the scene");
        }
        scene.build();
        scene
    }
}
