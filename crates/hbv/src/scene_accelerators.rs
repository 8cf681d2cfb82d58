//! One accelerator per ray type, chosen by configuration.

use std::sync::Arc;

use crate::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use crate::bvh::layout::Wide8Layout;
use crate::grid::{GridConfig, UniformGrid};
use crate::mesh::TriangleMesh;
use crate::Accelerator;

/// Which structure answers a kind of ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AcceleratorChoice {
    /// Binned-SAH tree in the 8-wide SIMD layout (the fastest BVH of `BENCHMARKS.md`).
    Bvh,
    /// [`UniformGrid`] with the given options.
    Grid(GridConfig),
}

impl AcceleratorChoice {
    /// Builds the chosen structure over `mesh`.
    pub fn build(&self, mesh: &TriangleMesh) -> Arc<dyn Accelerator> {
        match self {
            AcceleratorChoice::Bvh => {
                let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(mesh);
                Arc::new(Wide8Layout::new(&tree, mesh))
            }
            AcceleratorChoice::Grid(config) => Arc::new(UniformGrid::new(mesh, *config)),
        }
    }
}

/// Which structure answers each ray type. Default: the BVH for both.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneAcceleratorsConfig {
    /// Closest-hit rays: camera, reflected, transmitted, diffuse bounces.
    pub intersection: AcceleratorChoice,
    /// Any-hit rays towards lights.
    pub shadow: AcceleratorChoice,
}

impl Default for SceneAcceleratorsConfig {
    fn default() -> Self {
        Self {
            intersection: AcceleratorChoice::Bvh,
            shadow: AcceleratorChoice::Bvh,
        }
    }
}

/// A scene's accelerators, one per ray type, as the seed proposes ("grids for intersection
/// rays, HBV for shadow rays"; whether that pays is measured by `hbv experiment seed-claims`).
/// Both are shared handles: clone freely across threads. When both ray types choose the same
/// structure it is built once.
#[derive(Clone)]
pub struct SceneAccelerators {
    pub intersection: Arc<dyn Accelerator>,
    pub shadow: Arc<dyn Accelerator>,
}

impl SceneAccelerators {
    /// Builds the structures `config` names over `mesh`.
    pub fn new(mesh: &TriangleMesh, config: SceneAcceleratorsConfig) -> Self {
        let intersection = config.intersection.build(mesh);
        let shadow = if config.shadow == config.intersection {
            Arc::clone(&intersection)
        } else {
            config.shadow.build(mesh)
        };
        Self {
            intersection,
            shadow,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;
    use crate::mesh::procedural::icosphere;
    use glam::Vec3;

    #[test]
    fn grid_for_intersection_bvh_for_shadow_answer_alike() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 2);
        let scene = SceneAccelerators::new(
            &mesh,
            SceneAcceleratorsConfig {
                intersection: AcceleratorChoice::Grid(GridConfig::default()),
                shadow: AcceleratorChoice::Bvh,
            },
        );
        let ray = Ray::new(Vec3::new(0.1, 0.2, -4.0), Vec3::Z);
        let hit = scene.intersection.intersect(&ray).unwrap();
        assert!(scene.shadow.occluded(&ray));
        assert_eq!(scene.shadow.intersect(&ray), Some(hit));
        let shared = SceneAccelerators::new(&mesh, SceneAcceleratorsConfig::default());
        assert!(Arc::ptr_eq(&shared.intersection, &shared.shadow));
    }
}
