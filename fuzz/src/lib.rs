//! What the fuzz targets share: putting a loaded mesh through the rest of the pipeline.

use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::bvh::layout::{OrderedLayout, SkipLayout, Wide8Layout};
use hbv::bvh::BuildTree;
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::{Accelerator, BruteForce, TriangleMesh};

/// Meshes above this many triangles are only loaded: building keeps each run short.
const MAX_TRIANGLES_TO_BUILD: usize = 512;

/// Builds a tree over `mesh` (binned SAH, 8-wide layout) and traces rays from outside its box
/// towards its centre and along the axes, checking each answer against brute force.
pub fn exercise(mesh: &TriangleMesh) {
    if mesh.triangle_count() > MAX_TRIANGLES_TO_BUILD {
        return;
    }
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(mesh);
    let accel = Wide8Layout::new(&tree, mesh);
    let brute = BruteForce::new(mesh);
    let bounds = mesh.bounds();
    let centre = (bounds.min + bounds.max) * 0.5;
    let reach = (bounds.max - bounds.min).length() + 1.0;
    let directions = [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(1.0, 2.0, -3.0).normalize()];
    for d in directions {
        let ray = Ray::new(centre - d * reach, d);
        assert_eq!(accel.intersect(&ray), brute.intersect(&ray), "{ray:?}");
        assert_eq!(accel.occluded(&ray), brute.occluded(&ray), "{ray:?}");
    }
}

/// Lays `tree` (read from a file, so over `mesh`) out in the skip, ordered and 8-wide layouts and
/// traces the rays of [`exercise`] through each, checking every answer against brute force.
pub fn exercise_tree(tree: &BuildTree, mesh: &TriangleMesh) {
    if mesh.triangle_count() > MAX_TRIANGLES_TO_BUILD {
        return;
    }
    let brute = BruteForce::new(mesh);
    let layouts: [Box<dyn Accelerator>; 3] = [
        Box::new(SkipLayout::new(tree, mesh)),
        Box::new(OrderedLayout::new(tree, mesh)),
        Box::new(Wide8Layout::new(tree, mesh)),
    ];
    let bounds = mesh.bounds();
    let centre = (bounds.min + bounds.max) * 0.5;
    let reach = (bounds.max - bounds.min).length() + 1.0;
    for d in [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(1.0, 2.0, -3.0).normalize()] {
        let ray = Ray::new(centre - d * reach, d);
        for accel in &layouts {
            assert_eq!(accel.intersect(&ray), brute.intersect(&ray), "{ray:?}");
            assert_eq!(accel.occluded(&ray), brute.occluded(&ray), "{ray:?}");
        }
    }
}
