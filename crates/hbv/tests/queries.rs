//! Property tests: the BVH answers exactly what brute force answers, on adversarial inputs.

use glam::Vec3;
use hbv::bvh::build::{Builder, InsertionBuilder, InsertionConfig, InsertionOrder};
use hbv::bvh::layout::{Wide4Layout, Wide8Layout};
use hbv::geometry::Ray;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{
    assert_agrees, closed_mesh, every_layout, mesh_and_coherent_rays, mesh_and_rays, order, soup,
};

/// Every layout of the tree built with the given insertion options, by name.
fn layouts(
    mesh: &TriangleMesh,
    order: InsertionOrder,
    max_leaf_size: usize,
) -> Vec<(&'static str, Box<dyn Accelerator>)> {
    let tree = InsertionBuilder::new(InsertionConfig {
        order,
        max_leaf_size,
    })
    .build(mesh);
    every_layout(&tree, mesh)
}

/// [`assert_agrees`] for every layout.
fn assert_all_layouts_agree(
    mesh: &TriangleMesh,
    order: InsertionOrder,
    max_leaf_size: usize,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    for (name, accel) in layouts(mesh, order, max_leaf_size) {
        assert_agrees(mesh, accel.as_ref(), rays)
            .map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(common::cases(1000))]

    #[test]
    fn soup_closest_and_any_hit_equal_brute_force((mesh, rays) in mesh_and_rays(soup()), order in order(), leaf in 1usize..5) {
        assert_all_layouts_agree(&mesh, order, leaf, &rays)?;
    }

    #[test]
    fn closed_mesh_closest_and_any_hit_equal_brute_force((mesh, rays) in mesh_and_rays(closed_mesh()), order in order(), leaf in 1usize..5) {
        assert_all_layouts_agree(&mesh, order, leaf, &rays)?;
    }

    /// Batches of coherent rays (which the wide-8 layout traces eight at a time, as packets)
    /// answer exactly what single rays answer (which the tests above compare with brute force),
    /// on every layout, and on the wide-8 layout with its packets off.
    #[test]
    fn coherent_batches_answer_like_single_rays((mesh, rays) in mesh_and_coherent_rays(prop_oneof![soup(), closed_mesh()]), order in order(), leaf in 1usize..5) {
        let mut all = layouts(&mesh, order, leaf);
        let tree = InsertionBuilder::new(InsertionConfig { order, max_leaf_size: leaf }).build(&mesh);
        all.push(("wide8 without packets", Box::new(Wide8Layout::new(&tree, &mesh).with_ray_packets(false))));
        for (name, accel) in all {
            let single: Vec<_> = rays.iter().map(|r| accel.intersect(r)).collect();
            prop_assert_eq!(&accel.intersect_batch(&rays), &single, "{}", name);
            let blocked: Vec<_> = rays.iter().map(|r| accel.occluded(r)).collect();
            prop_assert_eq!(&accel.occluded_batch(&rays), &blocked, "{}", name);
        }
    }

    #[test]
    fn tree_invariants_hold((mesh, _) in mesh_and_rays(soup()), order in order(), leaf in 1usize..5) {
        let tree = InsertionBuilder::new(InsertionConfig { order, max_leaf_size: leaf }).build(&mesh);
        let bounds = hbv::bvh::build::primitive_bounds(&mesh);
        prop_assert!(tree.validate(&bounds, leaf).is_ok(), "{:?}", tree.validate(&bounds, leaf));
    }
}

#[test]
fn hits_at_exactly_tmin_and_tmax_count() {
    let mesh = torus(Vec3::ZERO, 2.0, 0.5, 16, 8);
    let all = layouts(&mesh, InsertionOrder::default(), 1);
    let reference = BruteForce::new(&mesh);
    let mut checked = 0;
    for k in 0..200 {
        let a = k as f32 * 0.1;
        let ray = Ray::new(Vec3::new(0.0, 0.0, 0.1), Vec3::new(a.cos(), a.sin(), 0.05));
        let Some(h) = reference.intersect(&ray) else {
            continue;
        };
        for r in [
            ray.with_interval(h.t, h.t),
            ray.with_interval(0.0, h.t),
            ray.with_interval(h.t, f32::INFINITY),
        ] {
            for (name, accel) in &all {
                assert_eq!(accel.intersect(&r), Some(h), "{name} {r:?}");
                assert!(accel.occluded(&r), "{name} {r:?}");
            }
        }
        checked += 1;
    }
    assert!(checked > 100);
}

#[test]
fn empty_and_all_degenerate_meshes_never_hit() {
    let ray = Ray::new(Vec3::new(0.1, 0.1, -1.0), Vec3::Z);
    for mesh in common::empty_and_all_degenerate_meshes() {
        for (name, accel) in layouts(&mesh, InsertionOrder::default(), 1) {
            assert_eq!(accel.intersect(&ray), None, "{name}");
            assert!(!accel.occluded(&ray), "{name}");
            assert_eq!(accel.intersect_batch(&[ray; 40]), vec![None; 40], "{name}");
            assert_eq!(accel.occluded_batch(&[ray; 40]), vec![false; 40], "{name}");
        }
    }
}

/// Builders make leaves of up to 255 triangles; the wide layouts hold at most 64 per leaf and
/// split larger ones under a node of their own, answering as before.
#[test]
fn wide_layouts_take_leaves_larger_than_theirs() {
    use hbv::bvh::build::{MedianBuilder, MedianConfig};
    let mesh = torus(Vec3::new(0.3, -0.2, 0.1), 2.0, 0.6, 40, 15);
    let tree = MedianBuilder::new(MedianConfig { max_leaf_size: 255 }).build(&mesh);
    let rays: Vec<Ray> = (0..400)
        .map(|k| {
            let a = k as f32 * 0.37;
            Ray::new(
                Vec3::new(5.0 * a.cos(), 0.9 * (k as f32 * 0.11).sin(), 5.0 * a.sin()),
                Vec3::new(-a.cos(), 0.05 * (k as f32).cos(), -a.sin() + 0.2),
            )
        })
        .collect();
    let wide4 = Wide4Layout::new(&tree, &mesh);
    let wide8 = Wide8Layout::new(&tree, &mesh);
    assert_agrees(&mesh, &wide4, &rays).unwrap();
    assert_agrees(&mesh, &wide8, &rays).unwrap();
    assert!(rays.iter().filter(|r| wide8.intersect(r).is_some()).count() > 100);
}

/// The interleaved batch traversal on a deep tree (a triangle soup whose sizes halve from one to
/// the next), with invalid rays among valid ones, on batches of lengths around the number of rays
/// it keeps in flight: each answer is the single ray's.
#[test]
fn batches_of_any_length_through_deep_trees_answer_like_single_rays() {
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for k in 0..120u32 {
        let s = 0.5f32.powi(k as i32 % 60) * if k >= 60 { -1.0 } else { 1.0 };
        let base = vertices.len() as u32;
        vertices.extend([
            Vec3::new(s, 0.0, 0.0),
            Vec3::new(s, s.abs(), 0.1),
            Vec3::new(s, 0.0, s.abs()),
        ]);
        faces.push([base, base + 1, base + 2]);
    }
    let mesh = TriangleMesh::new(vertices, faces).unwrap();
    let rays: Vec<Ray> = (0..70)
        .map(|i| {
            let y = 0.5f32.powi(i % 40) * 0.3;
            let ray = Ray::new(Vec3::new(-2.0, y, y * 0.5), Vec3::X);
            if i % 13 == 5 {
                Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X)
            } else {
                ray
            }
        })
        .collect();
    for leaf in [1, 4] {
        for (name, accel) in layouts(&mesh, InsertionOrder::default(), leaf) {
            for n in [0, 1, 15, 16, 17, 33, 70] {
                let rays = &rays[..n];
                let single: Vec<_> = rays.iter().map(|r| accel.intersect(r)).collect();
                assert_eq!(accel.intersect_batch(rays), single, "{name}, {n} rays");
                let single: Vec<_> = rays.iter().map(|r| accel.occluded(r)).collect();
                assert_eq!(accel.occluded_batch(rays), single, "{name}, {n} rays");
            }
        }
    }
}
