//! Hits much nearer the origin than the scene's coordinates are large, on finite segments.
//!
//! The triangle test's computed `t` carries an error of a few ulps of the coordinates; when the
//! hit is a tiny `t` away, that error is large relative to `t`, and a segment ending at the
//! computed `t` once let the box tests of the scalar layouts cull the box entered at the hit
//! (found by the cache property tests). Every layout must find what brute force finds.

use hbv::bvh::build::{BinnedSahBuilder, Builder};
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::mesh::procedural::torus;
use hbv::mesh::TriangleMesh;
use hbv::{Accelerator, BruteForce};

mod common;
use common::every_layout;

#[test]
fn segments_ending_at_a_near_hit_find_it_in_every_layout() {
    let mesh = torus(Vec3::ZERO, 2e-4, 7e-5, 5, 6);
    let tree = BinnedSahBuilder::default().build(&mesh);
    let layouts = every_layout(&tree, &mesh);
    let brute = BruteForce::new(&mesh);
    let origin = Vec3::new(-2.4261884e-5, -0.00013546088, 6.029243e-5);
    let mut checked = 0;
    for direction in [
        Vec3::new(0.9863853, 0.7942018, 0.8921853),
        Vec3::new(0.9879344, 0.7957509, 0.8937344),
    ] {
        let ray = Ray::new(origin, direction);
        let hit = brute
            .intersect(&ray)
            .expect("the ray leaves through the torus");
        let segment = ray.with_interval(0.0, hit.t);
        assert_eq!(brute.intersect(&segment), Some(hit));
        for (name, layout) in &layouts {
            assert_eq!(layout.intersect(&segment), Some(hit), "{name}");
            assert!(layout.occluded(&segment), "{name}");
            checked += 1;
        }
    }
    assert_eq!(checked, 10);
}

/// A direction component so small that `1/d` overflows to infinity, on a ray that still
/// crosses that axis's slab planes inside the scene: the slab test must not take the ray for
/// one parallel to the planes (and outside the slab), or it loses the hit.
#[test]
fn tiny_direction_components_whose_inverse_overflows_lose_no_hit() {
    // A square in the plane x = 0.5 over y in [0, 1], z in [0, 1]: the ray starts just below
    // y = 0 and rises by a subnormal slope, crossing y = 0 at x = 0 and meeting the square.
    let mesh = TriangleMesh::new(
        vec![
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, 1.0, 1.0),
            Vec3::new(0.5, 0.0, 1.0),
            // A second object, so that the tree has more than one leaf box to test.
            Vec3::new(3.0, 3.0, 3.0),
            Vec3::new(4.0, 3.0, 3.0),
            Vec3::new(3.0, 4.0, 3.0),
        ],
        vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
    )
    .unwrap();
    let tree = BinnedSahBuilder::default().build(&mesh);
    let layouts = every_layout(&tree, &mesh);
    let brute = BruteForce::new(&mesh);
    let mut checked = 0;
    for dy in [1e-40f32, 1e-44, 3e-39] {
        let origin = Vec3::new(-1.0, -dy, 0.5);
        let ray = Ray::new(origin, Vec3::new(1.0, dy, 0.0));
        let hit = brute.intersect(&ray).expect("the ray crosses the square");
        for (name, layout) in &layouts {
            assert_eq!(layout.intersect(&ray), Some(hit), "{name}, dy = {dy:e}");
            assert!(layout.occluded(&ray), "{name}, dy = {dy:e}");
            assert_eq!(layout.intersect_batch(&[ray])[0], Some(hit), "{name} batch");
            checked += 1;
        }
    }
    assert_eq!(checked, 15);
}
