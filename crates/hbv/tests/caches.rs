//! Property tests: the shadow and last-hit caches never change an answer, over sequences of
//! rays (coherent and not), wrapped around a BVH layout and around the grid.

use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
use hbv::cache::{LastHitCache, ShadowCache};
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce, TraversalStats, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{closed_mesh, every_layout, mesh_and_rays, soup};

fn accelerators(mesh: &TriangleMesh) -> Vec<(&'static str, Box<dyn Accelerator>)> {
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(mesh);
    let mut all = every_layout(&tree, mesh);
    all.push((
        "grid",
        Box::new(UniformGrid::new(mesh, GridConfig::default())),
    ));
    all
}

/// Each ray of `rays` followed by a slightly moved copy (a coherent neighbour, so that caches
/// hit), through both caches, against brute force.
fn check(mesh: &TriangleMesh, rays: &[Ray]) -> Result<(), TestCaseError> {
    let reference = BruteForce::new(mesh);
    let mut sequence = Vec::new();
    for r in rays {
        sequence.push(*r);
        let mut near = *r;
        near.direction += Vec3::splat(1e-3) * r.direction.length();
        sequence.push(near);
        sequence.push(*r);
    }
    for (name, accel) in accelerators(mesh) {
        let mut shadow = ShadowCache::new(accel.as_ref(), mesh);
        let mut last = LastHitCache::new(accel.as_ref(), mesh);
        let mut counted_shadow = ShadowCache::new(accel.as_ref(), mesh);
        let mut counted_last = LastHitCache::new(accel.as_ref(), mesh);
        let mut stats = TraversalStats::default();
        for ray in &sequence {
            let want = reference.intersect(ray);
            prop_assert_eq!(last.intersect(ray), want, "{} last-hit {:?}", name, ray);
            prop_assert_eq!(counted_last.intersect_counted(ray, &mut stats), want);
            let blocked = reference.occluded(ray);
            prop_assert_eq!(shadow.occluded(ray), blocked, "{} shadow {:?}", name, ray);
            prop_assert_eq!(counted_shadow.occluded_counted(ray, &mut stats), blocked);
            // The occluder an accelerator reports really blocks the ray.
            if let Some(prim) = accel.occluder(ray) {
                let t = mesh.triangle(prim as usize);
                let alone = TriangleMesh::new(vec![t.p0, t.p1, t.p2], vec![[0, 1, 2]]).unwrap();
                prop_assert!(
                    BruteForce::new(&alone).occluded(ray),
                    "{} occluder {}",
                    name,
                    prim
                );
            } else {
                prop_assert!(!blocked, "{} found no occluder", name);
            }
        }
        prop_assert_eq!(stats.rays, 2 * sequence.len() as u64);
        prop_assert_eq!(shadow.stats(), counted_shadow.stats());
        prop_assert_eq!(
            shadow.stats().hits + shadow.stats().misses,
            sequence.iter().filter(|r| r.is_valid()).count() as u64
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(common::cases(200))]

    #[test]
    fn caches_never_change_answers_on_soups((mesh, rays) in mesh_and_rays(soup())) {
        check(&mesh, &rays)?;
    }

    #[test]
    fn caches_never_change_answers_on_closed_meshes((mesh, rays) in mesh_and_rays(closed_mesh())) {
        check(&mesh, &rays)?;
    }
}

/// Coherent rays hit the caches; ties at equal `t` keep the smaller id under the last-hit cache.
#[test]
fn coherent_rays_hit_and_ties_keep_the_smaller_id() {
    let mesh = torus(Vec3::ZERO, 2.0, 0.7, 32, 16);
    let grid = UniformGrid::new(&mesh, GridConfig::default());
    let mut last = LastHitCache::new(&grid, &mesh);
    let mut shadow = ShadowCache::new(&grid, &mesh);
    let reference = BruteForce::new(&mesh);
    for k in 0..400 {
        let y = -1.0 + k as f32 * 0.005;
        let ray = Ray::new(Vec3::new(-5.0, y, 0.1), Vec3::X);
        assert_eq!(last.intersect(&ray), reference.intersect(&ray));
        assert_eq!(shadow.occluded(&ray), reference.occluded(&ray));
    }
    assert!(last.stats().hit_rate() > 0.5, "{:?}", last.stats());
    assert!(shadow.stats().hit_rate() > 0.5, "{:?}", shadow.stats());

    // Two coincident triangles: id 1 cached first must not win over id 0 at the same t.
    let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let twins = TriangleMesh::new(p.repeat(2), vec![[3, 4, 5], [0, 1, 2]]).unwrap();
    let grid = UniformGrid::new(&twins, GridConfig::default());
    let mut last = LastHitCache::new(&grid, &twins);
    let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
    for _ in 0..3 {
        assert_eq!(last.intersect(&ray).unwrap().prim, 0);
    }
}
