//! Property tests: the uniform grid (every configuration) answers exactly what brute force
//! answers, on the adversarial meshes and rays of `common`.

use hbv::geometry::Ray;
use hbv::glam::Vec3;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::mesh::procedural::{ground_plane, torus};
use hbv::{Accelerator, BruteForce, TriangleMesh};
use proptest::prelude::*;

mod common;
use common::{assert_agrees, closed_mesh, mesh_and_rays, soup};

fn config() -> impl Strategy<Value = GridConfig> {
    (
        prop_oneof![Just(0.3f64), Just(1.0), Just(2.0), Just(6.0)],
        any::<bool>(),
    )
        .prop_map(|(lambda, mailbox)| GridConfig { lambda, mailbox })
}

fn check(mesh: &TriangleMesh, config: GridConfig, rays: &[Ray]) -> Result<(), TestCaseError> {
    let grid = UniformGrid::new(mesh, config);
    assert_agrees(mesh, &grid, rays)
        .map_err(|e| TestCaseError::fail(format!("{config:?}: {e}")))?;
    // Exactly, not only within the tolerance of `assert_agrees`, and the blocking triangle
    // really blocks.
    let reference = BruteForce::new(mesh);
    for ray in rays {
        prop_assert_eq!(grid.intersect(ray), reference.intersect(ray), "{:?}", ray);
        if let Some(prim) = grid.occluder(ray) {
            let t = mesh.triangle(prim as usize);
            prop_assert!(BruteForce::new(
                &TriangleMesh::new(vec![t.p0, t.p1, t.p2], vec![[0, 1, 2]]).unwrap()
            )
            .occluded(ray));
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(common::cases(1000))]

    #[test]
    fn soup_equals_brute_force((mesh, rays) in mesh_and_rays(soup()), config in config()) {
        check(&mesh, config, &rays)?;
    }

    #[test]
    fn closed_mesh_equals_brute_force((mesh, rays) in mesh_and_rays(closed_mesh()), config in config()) {
        check(&mesh, config, &rays)?;
    }
}

/// A flat mesh (zero extent on z), rays along and across its plane.
#[test]
fn flat_mesh_and_rays_in_its_plane() {
    let mesh = ground_plane(1.0, 0.0, 8);
    let mut rays = Vec::new();
    for k in 0..200 {
        let x = -1.2 + 0.012 * k as f32;
        rays.push(Ray::new(Vec3::new(x, 0.3, 1.0), -Vec3::Z));
        rays.push(Ray::new(Vec3::new(x, -2.0, 0.0), Vec3::Y));
        rays.push(Ray::new(Vec3::new(x, 0.25, 0.0), Vec3::new(1.0, -0.5, 0.0)));
        rays.push(Ray::new(
            Vec3::new(x, 0.5, -0.0),
            Vec3::new(-0.0, 1.0, -0.0),
        ));
    }
    for mailbox in [false, true] {
        let grid = UniformGrid::new(
            &mesh,
            GridConfig {
                lambda: 2.0,
                mailbox,
            },
        );
        assert_agrees(&mesh, &grid, &rays).unwrap();
    }
}

/// Rays that start inside the grid, outside it, on its boundary, and on shared edges.
#[test]
fn torus_rays_from_everywhere() {
    let mesh = torus(Vec3::new(0.3, -0.2, 0.1), 2.0, 0.7, 24, 12);
    let b = mesh.bounds();
    let mut rays = Vec::new();
    for k in 0..500 {
        let f = k as f32 / 500.0;
        let target = b.min + (b.max - b.min) * Vec3::new(f, (7.0 * f).fract(), (13.0 * f).fract());
        let origin = b.min + (b.max - b.min) * Vec3::new((3.0 * f).fract(), (11.0 * f).fract(), f);
        rays.push(Ray::new(origin, target - origin));
        rays.push(Ray::new(target * 5.0, target - target * 5.0));
        rays.push(Ray::new(
            mesh.positions()[k % mesh.positions().len()],
            target - origin,
        ));
        rays.push(Ray::new(Vec3::new(b.min.x, target.y, target.z), Vec3::X));
    }
    let grid = UniformGrid::new(&mesh, GridConfig::default());
    assert_agrees(&mesh, &grid, &rays).unwrap();
}
