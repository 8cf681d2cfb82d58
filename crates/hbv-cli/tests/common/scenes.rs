//! Scenes the command-line tests trace (`scene_cli.rs`, `saved_scene_cli.rs`), and rays at them.

use hbv::geometry::Ray;
use hbv::glam::{DAffine3, DQuat, DVec3, Vec3};
use hbv::mesh::procedural::{icosphere, torus};
use hbv::scene::{InstanceTransform, Scene};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::{point_in_box, random_direction};

/// A scene of two meshes, each shared by several instances: spheres placed plainly, mirrored
/// (x → -x, a negative determinant) and scaled by 2.5, and tori rotated and scaled unevenly.
pub fn instanced_scene() -> Scene {
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 2));
    let ring = scene.add_mesh(torus(Vec3::ZERO, 1.5, 0.4, 24, 12));
    let place = |scale: DVec3, angle: f64, at: DVec3| {
        InstanceTransform::new(DAffine3::from_scale_rotation_translation(
            scale,
            DQuat::from_rotation_y(angle),
            at,
        ))
        .unwrap()
    };
    let transforms = [
        (sphere, place(DVec3::ONE, 0.0, DVec3::new(0.0, 0.0, 0.0))),
        (ring, place(DVec3::ONE, 0.7, DVec3::new(4.0, 0.5, 0.0))),
        // Mirrored: its normals flip.
        (
            sphere,
            place(DVec3::new(-1.0, 1.0, 1.0), 0.3, DVec3::new(-4.0, 0.0, 1.0)),
        ),
        (
            sphere,
            place(DVec3::splat(2.5), 1.1, DVec3::new(0.0, 0.0, 6.0)),
        ),
        (
            ring,
            place(DVec3::new(1.0, 3.0, 0.5), -0.4, DVec3::new(0.0, 4.0, -5.0)),
        ),
        // Overlapping the first sphere: closest hits must pick between instances.
        (
            sphere,
            place(DVec3::splat(0.8), 0.0, DVec3::new(0.5, 0.2, 0.0)),
        ),
    ];
    for (mesh, transform) in transforms {
        scene.add_instance(mesh, transform, u32::MAX).unwrap();
    }
    scene.build();
    scene
}

/// Rays at the scene: from outside its box at the centroids of random world triangles, and
/// from random points inside its box in random directions, some with a finite interval.
pub fn rays_at(scene: &Scene, count: usize, seed: u64) -> Vec<Ray> {
    let flat = scene.flattened().unwrap();
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let b = scene.bounds();
    let (lo, ext) = (b.min, b.extent());
    (0..count)
        .map(|i| {
            let dir = random_direction(&mut rng);
            let inside = point_in_box(&mut rng, lo, ext);
            match i % 3 {
                0 => {
                    let face = rng.random_range(0..flat.mesh.triangle_count());
                    let t = flat.mesh.triangle(face);
                    let target = (t.p0 + t.p1 + t.p2) / 3.0;
                    let origin = b.center() + dir * ext.length();
                    Ray::new(origin, target - origin)
                }
                1 => Ray::new(inside, dir),
                _ => Ray::new(inside, dir).with_interval(0.0, 0.2 * ext.length()),
            }
        })
        .collect()
}
