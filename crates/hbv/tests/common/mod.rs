//! What the property tests share: adversarial meshes and rays, and the comparison with brute
//! force. Each test file includes it (`mod common;`) and uses what it needs.

#![allow(dead_code)]

use hbv::bvh::build::InsertionOrder;
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, BruteForce, Hit, TriangleMesh};
use proptest::prelude::*;

mod cases;
// Unused by the files that run no property tests (box_margin.rs).
#[allow(unused_imports)]
pub use cases::cases;

/// Every layout over `tree`, by name.
pub fn every_layout(
    tree: &hbv::bvh::BuildTree,
    mesh: &TriangleMesh,
) -> Vec<(&'static str, Box<dyn Accelerator>)> {
    use hbv::bvh::layout::{OrderedLayout, RecursiveLayout, SkipLayout, Wide4Layout, Wide8Layout};
    vec![
        ("recursive", Box::new(RecursiveLayout::new(tree, mesh))),
        ("skip", Box::new(SkipLayout::new(tree, mesh))),
        ("ordered", Box::new(OrderedLayout::new(tree, mesh))),
        ("wide4", Box::new(Wide4Layout::new(tree, mesh))),
        ("wide8", Box::new(Wide8Layout::new(tree, mesh))),
    ]
}

/// Brute force and every layout over `tree` but the recursive one, by name.
pub fn every_accelerator(
    tree: &hbv::bvh::BuildTree,
    mesh: &TriangleMesh,
) -> Vec<(&'static str, Box<dyn Accelerator>)> {
    use hbv::bvh::layout::{OrderedLayout, SkipLayout, Wide4Layout, Wide8Layout};
    vec![
        ("brute force", Box::new(BruteForce::new(mesh))),
        ("skip", Box::new(SkipLayout::new(tree, mesh))),
        ("ordered", Box::new(OrderedLayout::new(tree, mesh))),
        ("wide4", Box::new(Wide4Layout::new(tree, mesh))),
        ("wide8", Box::new(Wide8Layout::new(tree, mesh))),
    ]
}

/// Asserts that `accel` and brute force agree on every ray: closest hits identical (same `t`,
/// same `prim` under the shared tie rule, same barycentrics), any-hit identical.
pub fn assert_agrees(
    mesh: &TriangleMesh,
    accel: &dyn Accelerator,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    let reference = BruteForce::new(mesh);
    for (i, ray) in rays.iter().enumerate() {
        let want = reference.intersect(ray);
        let got = accel.intersect(ray);
        match (want, got) {
            (None, None) => {}
            (Some(w), Some(g)) => {
                let rel = (w.t - g.t).abs() / w.t.abs().max(1e-30);
                prop_assert!(rel <= 1e-6, "ray {i} {ray:?}: t {} vs {}", w.t, g.t);
                if w.prim != g.prim {
                    prop_assert_eq!(
                        w.t,
                        g.t,
                        "ray {} {:?}: prims {} vs {}",
                        i,
                        ray,
                        w.prim,
                        g.prim
                    );
                }
            }
            _ => prop_assert!(false, "ray {i} {ray:?}: brute force {want:?}, BVH {got:?}"),
        }
        prop_assert_eq!(
            reference.occluded(ray),
            accel.occluded(ray),
            "any hit, ray {} {:?}",
            i,
            ray
        );
    }
    // The batch queries (interleaved traversal in the wide layouts) answer exactly what single
    // rays answer.
    let single: Vec<Option<Hit>> = rays.iter().map(|r| accel.intersect(r)).collect();
    prop_assert_eq!(accel.intersect_batch(rays), single, "closest hit, batch");
    let single: Vec<bool> = rays.iter().map(|r| accel.occluded(r)).collect();
    prop_assert_eq!(accel.occluded_batch(rays), single, "any hit, batch");
    Ok(())
}

pub fn order() -> impl Strategy<Value = InsertionOrder> {
    prop_oneof![
        Just(InsertionOrder::Input),
        Just(InsertionOrder::Morton),
        any::<u64>().prop_map(|seed| InsertionOrder::Shuffle { seed }),
    ]
}

/// A coordinate scale: tiny, unit, large and huge scenes.
pub fn scale() -> impl Strategy<Value = f32> {
    prop_oneof![Just(1e-4f32), Just(1.0), Just(1e3), Just(1e6)]
}

pub fn point(s: f32) -> impl Strategy<Value = Vec3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(move |(x, y, z)| Vec3::new(x, y, z) * s)
}

/// A triangle soup with slivers, degenerate (collinear, coincident) and huge triangles mixed in.
pub fn soup() -> impl Strategy<Value = TriangleMesh> {
    scale().prop_flat_map(|s| {
        let tri = prop_oneof![
            6 => (point(s), point(s), point(s)).prop_map(|(a, b, c)| [a, b, c]),
            // Small triangle around a point.
            3 => (point(s), point(s * 0.05), point(s * 0.05)).prop_map(|(a, b, c)| [a, a + b, a + c]),
            // Sliver: third vertex almost on the first edge.
            1 => (point(s), point(s), 0.0f32..1.0).prop_map(|(a, b, k)| [a, b, a + (b - a) * k + Vec3::splat(1e-6)]),
            // Degenerate: collinear or coincident.
            1 => (point(s), point(s)).prop_map(|(a, b)| [a, b, a + (b - a) * 0.5]),
            1 => point(s).prop_map(|a| [a, a, a]),
            // The same triangle every time: many coincident centroids.
            1 => Just([Vec3::ZERO, Vec3::X * s, Vec3::Y * s]),
            // Huge: much larger than the scene.
            1 => (point(s * 100.0), point(s * 100.0), point(s * 100.0)).prop_map(|(a, b, c)| [a, b, c]),
        ];
        prop::collection::vec(tri, 1..120).prop_map(|tris| {
            let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
            let indices = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
            TriangleMesh::new(positions, indices).unwrap()
        })
    })
}

/// Meshes without a triangle to hit: one with none, one whose triangles are all degenerate (a
/// collinear one and a point).
pub fn empty_and_all_degenerate_meshes() -> [TriangleMesh; 2] {
    let empty = TriangleMesh::new(vec![], vec![]).unwrap();
    let flat = TriangleMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        vec![[0, 1, 2], [0, 0, 0]],
    )
    .unwrap();
    [empty, flat]
}

/// A closed torus with shared edges, randomly sized and placed.
pub fn closed_mesh() -> impl Strategy<Value = TriangleMesh> {
    (scale(), 3u32..24, 3u32..12, point(1.0))
        .prop_map(|(s, m, n, c)| torus(c * s, 2.0 * s, 0.7 * s, m, n))
}

/// A ray aimed at the mesh in one of the adversarial ways.
pub fn ray_for(mesh: &TriangleMesh) -> impl Strategy<Value = Ray> {
    let b = mesh.bounds();
    let (lo, hi) = (b.min, b.max);
    let ext = (hi - lo).max_element().max(1e-30);
    let n = mesh.triangle_count();
    let inside = move || {
        (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0)
            .prop_map(move |(x, y, z)| lo + (hi - lo) * Vec3::new(x, y, z))
    };
    let dir = || point(1.0).prop_filter("nonzero", |d| d.length() > 1e-3);
    let axis = || {
        (0usize..3, any::<bool>(), any::<bool>()).prop_map(|(k, neg, negzero)| {
            let z = if negzero { -0.0 } else { 0.0 };
            let mut d = Vec3::splat(z);
            d[k] = if neg { -1.0 } else { 1.0 };
            d
        })
    };
    let mesh = mesh.clone();
    let on_surface = (0..n, 0.0f32..1.0, 0.0f32..1.0).prop_map(move |(i, a, b)| {
        let t = mesh.triangle(i);
        let (a, b) = if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        };
        t.p0 + (t.p1 - t.p0) * a + (t.p2 - t.p0) * b
    });
    prop_oneof![
        (inside(), dir()).prop_map(|(o, d)| Ray::new(o, d)),
        (inside(), axis()).prop_map(|(o, d)| Ray::new(o, d)),
        // Zero components in one or two axes.
        (inside(), dir(), 0usize..3).prop_map(|(o, mut d, k)| {
            d[k] = 0.0;
            if d == Vec3::ZERO {
                d.x = 1.0
            }
            Ray::new(o, d)
        }),
        // From outside at the box, with a scaled direction.
        (point(1.0), inside(), 0.01f32..100.0).prop_map(move |(o, target, k)| {
            let o = (lo + hi) * 0.5 + o.normalize_or(Vec3::X) * 3.0 * ext;
            Ray::new(o, (target - o) * k / ext)
        }),
        // From a surface point, with tmin = 0 or a little above.
        (
            on_surface.clone(),
            dir(),
            prop_oneof![Just(0.0f32), Just(1e-5 * ext)]
        )
            .prop_map(|(o, d, tmin)| Ray::new(o, d).with_interval(tmin, f32::INFINITY)),
        // Finite segments.
        (inside(), dir(), 0.0f32..1.0, 0.0f32..2.0)
            .prop_map(move |(o, d, a, len)| Ray::new(o, d).with_interval(a * ext, (a + len) * ext)),
        // Invalid rays: must miss.
        (
            inside(),
            prop_oneof![
                Just(Vec3::ZERO),
                Just(Vec3::new(f32::NAN, 1.0, 0.0)),
                Just(Vec3::new(f32::INFINITY, 0.0, 0.0))
            ]
        )
            .prop_map(|(o, d)| Ray::new(o, d)),
    ]
}

pub fn mesh_and_rays(
    mesh: impl Strategy<Value = TriangleMesh>,
) -> impl Strategy<Value = (TriangleMesh, Vec<Ray>)> {
    mesh.prop_flat_map(|m| {
        let rays = prop::collection::vec(ray_for(&m), 1..64);
        (Just(m), rays)
    })
}

/// Packets of coherent rays, as camera rays are: groups of eight (the wide-8 layout's packets)
/// from one origin (or origins a hair apart) with directions a small random angle around an
/// adversarial base direction (random, along an axis, with zero components), some with finite
/// intervals, some invalid. Consecutive groups are independent.
pub fn coherent_rays_for(mesh: &TriangleMesh) -> impl Strategy<Value = Vec<Ray>> {
    let packet_size = 8;
    let single = ray_for(mesh);
    let spread = prop_oneof![Just(0.0f32), 1e-6f32..1e-3, 1e-3f32..0.2];
    let b = mesh.bounds();
    let ext = (b.max - b.min).max_element().max(1e-30);
    let packet = (
        single,
        spread,
        any::<bool>(),
        prop::collection::vec((point(1.0), point(1.0), 0u8..16), packet_size),
    )
        .prop_map(move |(base, spread, shift_origins, jitter)| {
            jitter
                .into_iter()
                .map(|(dj, oj, kind)| {
                    let mut ray = base;
                    ray.direction += dj * spread * base.direction.length();
                    if shift_origins {
                        ray.origin += oj * 1e-4 * ext;
                    }
                    match kind {
                        0 => ray.direction = Vec3::ZERO,
                        1 => ray.tmax = ray.tmin,
                        2 => ray.tmax = 0.5 * ext,
                        _ => {}
                    }
                    ray
                })
                .collect::<Vec<_>>()
        });
    prop::collection::vec(packet, 1..6).prop_map(|packets| packets.concat())
}

/// A mesh with coherent packets of rays; see [`coherent_rays_for`].
pub fn mesh_and_coherent_rays(
    mesh: impl Strategy<Value = TriangleMesh>,
) -> impl Strategy<Value = (TriangleMesh, Vec<Ray>)> {
    mesh.prop_flat_map(|m| {
        let rays = coherent_rays_for(&m);
        (Just(m), rays)
    })
}

/// The distance between the ray's line and the segment `a`–`b`, in f64: how near the line
/// passes to an edge (the scene tests excuse rays within the accuracy bound of one).
pub fn line_segment_distance(ray: &Ray, a: hbv::glam::DVec3, b: hbv::glam::DVec3) -> f64 {
    let o = ray.origin.as_dvec3();
    let d = ray.direction.as_dvec3().normalize();
    let across = |v: hbv::glam::DVec3| v - d * v.dot(d);
    let (a, e) = (across(a - o), across(b - a));
    let r = if e.length_squared() > 0.0 {
        (-a.dot(e) / e.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + r * e).length()
}
