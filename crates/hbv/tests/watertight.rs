//! No ray slips through a closed mesh: rays from inside aimed exactly at vertices, edge midpoints
//! and face centres always hit, through the BVH and through brute force.

use glam::Vec3;
use hbv::bvh::build::{Builder, InsertionBuilder, InsertionConfig};
use hbv::bvh::layout::RecursiveLayout;
use hbv::geometry::Ray;
use hbv::mesh::procedural::{icosphere, torus};
use hbv::{Accelerator, BruteForce, TriangleMesh};

/// Vertices, edge midpoints (computed in f32) and face centres of `mesh`.
fn targets(mesh: &TriangleMesh) -> Vec<Vec3> {
    let mut t: Vec<Vec3> = mesh.positions().to_vec();
    for tri in mesh.triangles() {
        t.extend([
            (tri.p0 + tri.p1) * 0.5,
            (tri.p1 + tri.p2) * 0.5,
            (tri.p2 + tri.p0) * 0.5,
            tri.centroid(),
        ]);
    }
    t
}

/// Fires a ray from every origin at every target and returns how many missed, for both the BVH
/// and brute force.
fn misses(mesh: &TriangleMesh, origins: &[Vec3]) -> (usize, usize, usize) {
    let tree = InsertionBuilder::new(InsertionConfig::default()).build(mesh);
    let bvh = RecursiveLayout::new(&tree, mesh);
    let brute = BruteForce::new(mesh);
    let targets = targets(mesh);
    let rays: Vec<Ray> = origins
        .iter()
        .flat_map(|&o| targets.iter().map(move |&t| Ray::new(o, t - o)))
        .collect();
    let bvh_misses = bvh
        .intersect_batch(&rays)
        .iter()
        .filter(|h| h.is_none())
        .count();
    let brute_misses = brute
        .intersect_batch(&rays)
        .iter()
        .filter(|h| h.is_none())
        .count();
    let occlusion_misses = bvh.occluded_batch(&rays).iter().filter(|&&o| !o).count();
    (bvh_misses, brute_misses, occlusion_misses)
}

#[test]
fn icospheres_are_watertight_at_vertices_and_edges() {
    for (center, radius) in [
        (Vec3::ZERO, 1.0),
        (Vec3::new(1e3, -2e3, 5e2), 3.7),
        (Vec3::new(0.1, 0.2, 0.3), 1e-3),
        (Vec3::new(-7e4, 3e4, 1e4), 250.0),
    ] {
        for subdivisions in [0, 2, 3] {
            let mesh = icosphere(center, radius, subdivisions);
            let origins = [
                center,
                center + Vec3::new(0.3, -0.2, 0.1) * radius,
                // Inside even the coarsest sphere: the inradius of an icosahedron is 0.79 of its circumradius.
                center + Vec3::new(-0.41, 0.3, 0.46) * radius,
            ];
            let m = misses(&mesh, &origins);
            assert_eq!(
                m,
                (0, 0, 0),
                "icosphere at {center} radius {radius} subdivisions {subdivisions}"
            );
        }
    }
}

#[test]
fn tori_are_watertight_at_vertices_and_edges() {
    for (center, scale) in [(Vec3::ZERO, 1.0), (Vec3::new(3e3, 1e3, -2e3), 17.0)] {
        let mesh = torus(center, 2.0 * scale, 0.6 * scale, 48, 24);
        // Points inside the tube: on the core circle and off it.
        let origins: Vec<Vec3> = (0..6)
            .map(|k| {
                let a = k as f32 * 1.1;
                let r = (2.0 + 0.3 * (k as f32 - 2.5) / 2.5) * scale;
                center
                    + Vec3::new(
                        r * a.cos(),
                        r * a.sin(),
                        0.2 * scale * (k as f32 - 3.0) / 3.0,
                    )
            })
            .collect();
        assert_eq!(
            misses(&mesh, &origins),
            (0, 0, 0),
            "torus at {center} scale {scale}"
        );
    }
}
