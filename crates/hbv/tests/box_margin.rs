//! Hits much nearer the origin than the scene's coordinates are large, on finite segments.
//!
//! The triangle test's computed `t` carries an error of a few ulps of the coordinates; when the
//! hit is a tiny `t` away, that error is large relative to `t`, and a segment ending at the
//! computed `t` once let the box tests of the scalar layouts cull the box entered at the hit
//! (found by the cache property tests). Every layout must find what brute force finds.

use hbv::bvh::build::{BinnedSahBuilder, Builder};
use hbv::bvh::layout::{OrderedLayout, RecursiveLayout, SkipLayout, Wide4Layout, Wide8Layout};
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce};

#[test]
fn segments_ending_at_a_near_hit_find_it_in_every_layout() {
    let mesh = torus(Vec3::ZERO, 2e-4, 7e-5, 5, 6);
    let tree = BinnedSahBuilder::default().build(&mesh);
    let layouts: Vec<(&str, Box<dyn Accelerator>)> = vec![
        ("recursive", Box::new(RecursiveLayout::new(&tree, &mesh))),
        ("skip", Box::new(SkipLayout::new(&tree, &mesh))),
        ("ordered", Box::new(OrderedLayout::new(&tree, &mesh))),
        ("wide4", Box::new(Wide4Layout::new(&tree, &mesh))),
        ("wide8", Box::new(Wide8Layout::new(&tree, &mesh))),
    ];
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
