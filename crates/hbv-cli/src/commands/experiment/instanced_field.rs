//! The built-in scene of many instances sharing meshes (`hbv experiment seed-claims
//! --scene-default`): made in code, so that it runs on a fresh clone.

use std::f64::consts::{FRAC_PI_2, TAU};

use glam::{DAffine3, DQuat, DVec3, Vec3};
use hbv::mesh::procedural::{default_scene, ground_plane, icosphere, torus};
use hbv::scene::{InstanceTransform, Scene};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Instances of the built-in field unless `--instances` says otherwise.
pub const DEFAULT_FIELD_INSTANCES: u32 = 300;

/// The seed of the field's placements.
const FIELD_SEED: u64 = 0xf1e1d;

/// A field of `instances` objects on a ground plane (one more instance, 32 large triangles),
/// sharing three meshes:
/// an icosphere (5,120 triangles), a torus (4,608) and the built-in mesh scene at detail 1
/// (4,560, a small diorama), each built once. The objects stand on a square grid 4 units apart,
/// jittered by up to 1, turned about the vertical at random, scaled by 0.5–1.5 (one in five
/// unevenly, one in seven mirrored); the tori stand upright. Placements draw from
/// [`FIELD_SEED`], so the same count gives the same scene.
pub fn instanced_field(instances: u32) -> Scene {
    let mut rng = Pcg64Mcg::seed_from_u64(FIELD_SEED);
    let mut scene = Scene::new();
    let sphere = scene.add_mesh(icosphere(Vec3::ZERO, 1.0, 4));
    let ring = scene.add_mesh(torus(Vec3::ZERO, 1.0, 0.35, 64, 36));
    let diorama = scene.add_mesh(default_scene(1));
    let ground = scene.add_mesh(ground_plane(1.0, 0.0, 4));

    let columns = (instances as f64).sqrt().ceil().max(1.0) as u32;
    let spacing = 4.0;
    let half = spacing * columns as f64 / 2.0;
    let place = |affine: DAffine3| {
        InstanceTransform::new(affine).expect("the field's transforms are invertible")
    };
    for k in 0..instances {
        let (row, column) = (k / columns, k % columns);
        let at = DVec3::new(
            -half + spacing * (column as f64 + 0.5) + rng.random_range(-1.0..1.0),
            -half + spacing * (row as f64 + 0.5) + rng.random_range(-1.0..1.0),
            0.0,
        );
        let size: f64 = rng.random_range(0.5..1.5);
        let mut scale = DVec3::splat(size);
        if rng.random_range(0..5) == 0 {
            scale.z *= rng.random_range(0.5..2.0);
        }
        if rng.random_range(0..7) == 0 {
            scale.x = -scale.x;
        }
        let turn = DQuat::from_rotation_z(rng.random_range(0.0..TAU));
        let (mesh, stand, lift) = match k % 3 {
            0 => (sphere, DQuat::IDENTITY, scale.z),
            // Upright: the local y axis, of extent 1.35, points up.
            1 => (ring, DQuat::from_rotation_x(FRAC_PI_2), 1.35 * scale.y),
            // The diorama is 20 units wide: shrink it to about 2, its own ground a little above
            // the field's (not coplanar: the two would tie).
            _ => {
                scale *= 0.1;
                (diorama, DQuat::IDENTITY, 0.02)
            }
        };
        let affine =
            DAffine3::from_scale_rotation_translation(scale, turn * stand, at + DVec3::Z * lift);
        scene
            .add_instance(mesh, place(affine), u32::MAX)
            .expect("the field's meshes exist");
    }
    let ground_transform = DAffine3::from_scale_rotation_translation(
        DVec3::new(half, half, 1.0),
        DQuat::IDENTITY,
        DVec3::ZERO,
    );
    scene
        .add_instance(ground, place(ground_transform), u32::MAX)
        .expect("the field's meshes exist");
    scene.build();
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_field_shares_its_meshes() {
        let scene = instanced_field(30);
        assert_eq!(scene.mesh_count(), 4);
        assert_eq!(scene.instance_count(), 31);
        let flat = scene.flattened().unwrap();
        // 10 instances of each object mesh and the ground.
        let seen = 10 * (5_120 + 4_608 + default_scene(1).triangle_count()) + 32;
        assert_eq!(flat.mesh.triangle_count(), seen);
        // Every object stands on the ground (z ≥ 0 up to rounding), inside its square.
        let bounds = scene.bounds();
        assert!(bounds.min.z > -1e-3, "{bounds:?}");
    }
}
