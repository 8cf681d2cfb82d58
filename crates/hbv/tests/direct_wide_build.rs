//! Property tests of the direct wide build (`WideLayout::build_direct`): its layouts answer
//! closest hit, any hit and every hit exactly as brute force does, on adversarial meshes and
//! rays, and hold the wide layout's invariants.

use hbv::bvh::build::{BinnedSahConfig, LeafPolicy};
use hbv::bvh::layout::{Wide4Layout, Wide8Layout};
use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::mesh::procedural::torus;
use hbv::{Accelerator, AllHits, BruteForce, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{assert_agrees, closed_mesh, mesh_and_coherent_rays, mesh_and_rays, soup};

/// The binned SAH options of one case: `bins` per axis, leaves of at most `leaf` triangles.
fn config(bins: usize, leaf: usize) -> BinnedSahConfig {
    BinnedSahConfig {
        bins,
        leaf: LeafPolicy::with_max_leaf_size(leaf),
    }
}

/// Both widths of the direct build over `mesh`, checked for the layout's invariants.
fn layouts(mesh: &TriangleMesh, config: &BinnedSahConfig) -> Vec<(&'static str, Box<dyn Wide>)> {
    let wide4 = Wide4Layout::build_direct(mesh, config);
    let wide8 = Wide8Layout::build_direct(mesh, config);
    wide4.validate(mesh).unwrap();
    wide8.validate(mesh).unwrap();
    vec![("wide4", Box::new(wide4)), ("wide8", Box::new(wide8))]
}

/// What the tests ask of a layout: the ray queries and every hit.
trait Wide: Accelerator + AllHits {}
impl<T: Accelerator + AllHits> Wide for T {}

/// Closest hit, any hit (single rays and batches: `assert_agrees`) and every hit along each ray
/// equal brute force's, for both widths.
fn assert_direct_build_agrees(
    mesh: &TriangleMesh,
    config: &BinnedSahConfig,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    let reference = BruteForce::new(mesh);
    let (mut want, mut got) = (Vec::new(), Vec::new());
    for (name, layout) in layouts(mesh, config) {
        assert_agrees(mesh, layout.as_ref() as &dyn Accelerator, rays)
            .map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
        for (i, ray) in rays.iter().enumerate() {
            reference.all_hits(ray, &mut want);
            layout.all_hits(ray, &mut got);
            prop_assert_eq!(&want, &got, "{}: every hit, ray {} {:?}", name, i, ray);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(common::cases(1000))]

    #[test]
    fn soup_hits_equal_brute_force((mesh, rays) in mesh_and_rays(soup()), bins in 2usize..=64, leaf in 1usize..70) {
        assert_direct_build_agrees(&mesh, &config(bins, leaf), &rays)?;
    }

    #[test]
    fn closed_mesh_hits_equal_brute_force((mesh, rays) in mesh_and_rays(closed_mesh()), bins in 2usize..=64, leaf in 1usize..70) {
        assert_direct_build_agrees(&mesh, &config(bins, leaf), &rays)?;
    }

    /// Batches of coherent rays (packets in the wide-8 layout) answer what single rays answer.
    #[test]
    fn coherent_batches_answer_like_single_rays((mesh, rays) in mesh_and_coherent_rays(prop_oneof![soup(), closed_mesh()]), leaf in 1usize..9) {
        for (name, layout) in layouts(&mesh, &config(32, leaf)) {
            let single: Vec<_> = rays.iter().map(|r| layout.intersect(r)).collect();
            prop_assert_eq!(&layout.intersect_batch(&rays), &single, "{}", name);
            let blocked: Vec<_> = rays.iter().map(|r| layout.occluded(r)).collect();
            prop_assert_eq!(&layout.occluded_batch(&rays), &blocked, "{}", name);
        }
    }
}

/// Rays from a ring around `mesh`'s box, aimed at points in it.
fn rays_at(mesh: &TriangleMesh, count: usize) -> Vec<Ray> {
    let b = mesh.bounds();
    let (centre, size) = (b.center(), b.extent().length());
    (0..count)
        .map(|k| {
            let a = k as f32 * 0.37;
            let origin = centre + size * Vec3::new(a.cos(), 0.3 * (k as f32 * 0.11).sin(), a.sin());
            let target = b.min
                + b.extent()
                    * Vec3::new(
                        0.5 + 0.4 * (a * 1.3).sin(),
                        0.5,
                        0.5 + 0.4 * (a * 0.7).cos(),
                    );
            Ray::new(origin, target - origin)
        })
        .collect()
}

/// A mesh larger than one build task (subtrees of 4,096 triangles or more are built apart and
/// joined): the joined layout holds every triangle once and answers as brute force, on any
/// number of threads.
#[test]
fn subtrees_built_in_parallel_join_into_one_layout() {
    let mesh = torus(Vec3::new(0.2, -0.1, 0.3), 2.0, 0.6, 300, 100);
    assert!(mesh.triangle_count() > 8 * 4096);
    let rays = rays_at(&mesh, 500);
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let layouts = pool.install(|| layouts(&mesh, &BinnedSahConfig::default()));
        for (name, layout) in layouts {
            assert_agrees(&mesh, layout.as_ref() as &dyn Accelerator, &rays)
                .unwrap_or_else(|e| panic!("{name}, {threads} threads: {e}"));
        }
    }
    assert!(
        rays.iter()
            .filter(|r| BruteForce::new(&mesh).occluded(r))
            .count()
            > 100
    );
}

/// Empty meshes, meshes of degenerate triangles only, and one triangle.
#[test]
fn empty_degenerate_and_single_triangle_meshes() {
    let ray = Ray::new(Vec3::new(0.1, 0.1, -1.0), Vec3::Z);
    for mesh in common::empty_and_all_degenerate_meshes() {
        for (name, layout) in layouts(&mesh, &BinnedSahConfig::default()) {
            assert_eq!(layout.intersect(&ray), None, "{name}");
            assert!(!layout.occluded(&ray), "{name}");
            assert_eq!(layout.intersect_batch(&[ray; 40]), vec![None; 40], "{name}");
        }
    }
    let one = TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap();
    for (name, layout) in layouts(&one, &BinnedSahConfig::default()) {
        assert_eq!(layout.intersect(&ray).map(|h| h.prim), Some(0), "{name}");
    }
}

/// Thousands of copies of one triangle (no bin boundary separates them: median splits all the
/// way down) and triangles nested with halving sizes (chains past the SAH's depth limit).
#[test]
fn coincident_and_nested_triangles() {
    let copies = 5000u32;
    let positions: Vec<Vec3> = (0..copies)
        .flat_map(|_| [Vec3::ZERO, Vec3::X, Vec3::Y])
        .collect();
    let indices = (0..copies).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let coincident = TriangleMesh::new(positions, indices).unwrap();
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for k in 0..150u32 {
        let s = 0.8f32.powi(k as i32);
        positions.extend([
            Vec3::new(s, 0.0, 0.0),
            Vec3::new(0.0, s, 0.0),
            Vec3::new(0.0, 0.0, s),
        ]);
        indices.push([3 * k, 3 * k + 1, 3 * k + 2]);
    }
    let nested = TriangleMesh::new(positions, indices).unwrap();
    for mesh in [coincident, nested] {
        let rays = rays_at(&mesh, 200);
        for (name, layout) in layouts(&mesh, &config(16, 4)) {
            assert_agrees(&mesh, layout.as_ref() as &dyn Accelerator, &rays)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }
}
