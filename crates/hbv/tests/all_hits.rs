//! Property tests: every hit along a ray, from the wide layouts and the uniform grid, equals
//! brute force's list.

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, InsertionBuilder, InsertionConfig,
};
use hbv::bvh::layout::{Wide4Layout, Wide8Layout};
use hbv::geometry::Ray;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::{AllHits, BruteForce, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{closed_mesh, mesh_and_rays, order, soup};

/// The wide layouts of an insertion tree and a binned-SAH tree, and uniform grids (sparse and
/// dense, with and without mailboxes; `leaf` picks the configuration).
fn structures(
    mesh: &TriangleMesh,
    order: hbv::bvh::build::InsertionOrder,
    leaf: usize,
) -> Vec<(&'static str, Box<dyn AllHits>)> {
    let insertion = InsertionBuilder::new(InsertionConfig {
        order,
        max_leaf_size: leaf,
    })
    .build(mesh);
    let mut config = BinnedSahConfig::default();
    config.leaf.max_leaf_size = leaf;
    let sah = BinnedSahBuilder::new(config).build(mesh);
    vec![
        (
            "insertion wide4",
            Box::new(Wide4Layout::new(&insertion, mesh)),
        ),
        (
            "insertion wide8",
            Box::new(Wide8Layout::new(&insertion, mesh)),
        ),
        ("binned-sah wide8", Box::new(Wide8Layout::new(&sah, mesh))),
        (
            "uniform grid",
            Box::new(UniformGrid::new(
                mesh,
                GridConfig {
                    lambda: [0.3, 1.0, 2.0, 6.0][leaf % 4],
                    mailbox: leaf.is_multiple_of(2),
                },
            )),
        ),
    ]
}

fn assert_all_hits_agree(
    mesh: &TriangleMesh,
    order: hbv::bvh::build::InsertionOrder,
    leaf: usize,
    rays: &[Ray],
) -> Result<(), TestCaseError> {
    let reference = BruteForce::new(mesh);
    let (mut want, mut got) = (Vec::new(), Vec::new());
    for (name, accel) in structures(mesh, order, leaf) {
        for (i, ray) in rays.iter().enumerate() {
            reference.all_hits(ray, &mut want);
            accel.all_hits(ray, &mut got);
            prop_assert_eq!(&want, &got, "{}: ray {} {:?}", name, i, ray);
            prop_assert_eq!(accel.count_hits(ray), want.len());
        }
        // The batch forms: the same hits, flattened in ray order.
        let flat = accel.all_hits_batch(rays);
        let counts = accel.count_hits_batch(rays);
        prop_assert_eq!(flat.len() as u32, counts.iter().sum::<u32>());
        let mut at = 0;
        for (i, ray) in rays.iter().enumerate() {
            reference.all_hits(ray, &mut want);
            let mine: Vec<_> = flat[at..at + want.len()].to_vec();
            prop_assert!(mine.iter().all(|(r, _)| *r == i as u32));
            prop_assert_eq!(
                mine.iter().map(|(_, h)| *h).collect::<Vec<_>>(),
                want.clone()
            );
            at += want.len();
        }
        // A batch of more than two runs of rays (shared between the calling thread and the
        // pool's threads rather than kept on the calling thread): the rays repeated, the same
        // hits, in ray order.
        if !rays.is_empty() {
            let long: Vec<Ray> = rays.iter().cycle().take(3 * 256 + 1).copied().collect();
            let mut expected = Vec::new();
            for (i, ray) in long.iter().enumerate() {
                accel.all_hits(ray, &mut got);
                expected.extend(got.iter().map(|&h| (i as u32, h)));
            }
            prop_assert_eq!(
                accel.all_hits_batch(&long),
                expected,
                "{}: long batch",
                name
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(common::cases(300))]

    #[test]
    fn soup_all_hits_equal_brute_force((mesh, rays) in mesh_and_rays(soup()), order in order(), leaf in 1usize..9) {
        assert_all_hits_agree(&mesh, order, leaf, &rays)?;
    }

    #[test]
    fn closed_mesh_all_hits_equal_brute_force((mesh, rays) in mesh_and_rays(closed_mesh()), order in order(), leaf in 1usize..9) {
        assert_all_hits_agree(&mesh, order, leaf, &rays)?;
    }
}

#[test]
fn a_ray_through_a_sphere_hits_twice_in_order() {
    let mesh = hbv::mesh::procedural::icosphere(hbv::glam::Vec3::ZERO, 1.0, 3);
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(&mesh);
    let bvh = Wide8Layout::new(&tree, &mesh);
    let ray = Ray::new(hbv::glam::Vec3::new(0.013, 0.027, -5.0), hbv::glam::Vec3::Z);
    let mut hits = Vec::new();
    bvh.all_hits(&ray, &mut hits);
    assert_eq!(hits.len(), 2);
    assert!(hits[0].t < hits[1].t);
    assert!((hits[0].t - 4.0).abs() < 0.05 && (hits[1].t - 6.0).abs() < 0.05);
}
