//! The built-in scene: the Cornell box with its published dimensions (Cornell University Program
//! of Computer Graphics, "Cornell Box Data", 1998; millimetres, the camera looking along +z),
//! its tall block turned into a mirror and a glass ball on its short block.

use glam::Vec3;
use hbv::mesh::procedural::icosphere;
use hbv::TriangleMesh;

use super::{RenderSettings, Scene, SceneAssembly, Transform};
use crate::camera::Camera;
use crate::light::Light;
use crate::material::{Material, Surface};

/// Quads of the published data, each `[p0, p1, p2, p3]` as listed there.
type Quad = [[f32; 3]; 4];

const FLOOR: Quad = [
    [552.8, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 559.2],
    [549.6, 0.0, 559.2],
];
const CEILING: Quad = [
    [556.0, 548.8, 0.0],
    [556.0, 548.8, 559.2],
    [0.0, 548.8, 559.2],
    [0.0, 548.8, 0.0],
];
const BACK_WALL: Quad = [
    [549.6, 0.0, 559.2],
    [0.0, 0.0, 559.2],
    [0.0, 548.8, 559.2],
    [556.0, 548.8, 559.2],
];
const RIGHT_WALL: Quad = [
    [0.0, 0.0, 559.2],
    [0.0, 0.0, 0.0],
    [0.0, 548.8, 0.0],
    [0.0, 548.8, 559.2],
];
const LEFT_WALL: Quad = [
    [552.8, 0.0, 0.0],
    [549.6, 0.0, 559.2],
    [556.0, 548.8, 559.2],
    [556.0, 548.8, 0.0],
];
const SHORT_BLOCK: [Quad; 5] = [
    [
        [130.0, 165.0, 65.0],
        [82.0, 165.0, 225.0],
        [240.0, 165.0, 272.0],
        [290.0, 165.0, 114.0],
    ],
    [
        [290.0, 0.0, 114.0],
        [290.0, 165.0, 114.0],
        [240.0, 165.0, 272.0],
        [240.0, 0.0, 272.0],
    ],
    [
        [130.0, 0.0, 65.0],
        [130.0, 165.0, 65.0],
        [290.0, 165.0, 114.0],
        [290.0, 0.0, 114.0],
    ],
    [
        [82.0, 0.0, 225.0],
        [82.0, 165.0, 225.0],
        [130.0, 165.0, 65.0],
        [130.0, 0.0, 65.0],
    ],
    [
        [240.0, 0.0, 272.0],
        [240.0, 165.0, 272.0],
        [82.0, 165.0, 225.0],
        [82.0, 0.0, 225.0],
    ],
];
const TALL_BLOCK: [Quad; 5] = [
    [
        [423.0, 330.0, 247.0],
        [265.0, 330.0, 296.0],
        [314.0, 330.0, 456.0],
        [472.0, 330.0, 406.0],
    ],
    [
        [423.0, 0.0, 247.0],
        [423.0, 330.0, 247.0],
        [472.0, 330.0, 406.0],
        [472.0, 0.0, 406.0],
    ],
    [
        [472.0, 0.0, 406.0],
        [472.0, 330.0, 406.0],
        [314.0, 330.0, 456.0],
        [314.0, 0.0, 456.0],
    ],
    [
        [314.0, 0.0, 456.0],
        [314.0, 330.0, 456.0],
        [265.0, 330.0, 296.0],
        [265.0, 0.0, 296.0],
    ],
    [
        [265.0, 0.0, 296.0],
        [265.0, 330.0, 296.0],
        [423.0, 330.0, 247.0],
        [423.0, 0.0, 247.0],
    ],
];
/// The light's opening in the ceiling: x ∈ [213, 343], z ∈ [227, 332], just below y = 548.8.
const LIGHT_CORNER: [f32; 3] = [343.0, 548.7, 227.0];
const LIGHT_SIZE: [f32; 2] = [130.0, 105.0];

/// Each quad as two triangles `(p0, p1, p2)`, `(p0, p2, p3)`; vertices not shared between quads,
/// so that the blocks stay flat-shaded.
fn quads(quads: &[Quad]) -> TriangleMesh {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for q in quads {
        let base = positions.len() as u32;
        positions.extend(q.iter().map(|&p| Vec3::from(p)));
        indices.push([base, base + 1, base + 2]);
        indices.push([base, base + 2, base + 3]);
    }
    TriangleMesh::new(positions, indices).expect("the box's quads are finite and indexed")
}

/// The built-in scene (see the module's documentation). 1,300 triangles.
pub fn cornell_box() -> Scene {
    let diffuse = |r, g, b| {
        Material::new(Surface::Diffuse {
            albedo: Vec3::new(r, g, b),
        })
    };
    let materials = vec![
        diffuse(0.73, 0.73, 0.73),
        diffuse(0.63, 0.065, 0.05),
        diffuse(0.14, 0.45, 0.091),
        Material::new(Surface::Mirror {
            reflectance: Vec3::splat(0.9),
        }),
        Material::new(Surface::Glass {
            ior: 1.5,
            tint: Vec3::ONE,
        }),
        Material {
            surface: Surface::Diffuse { albedo: Vec3::ZERO },
            emission: light_radiance(),
        },
    ];
    let [white, red, green, mirror, glass, lamp] = [0, 1, 2, 3, 4, 5];
    let place = Transform::default();
    let mut scene = SceneAssembly::default();
    let objects: [(&str, TriangleMesh, u32, bool); 7] = [
        (
            "floor, ceiling and back wall",
            quads(&[FLOOR, CEILING, BACK_WALL]),
            white,
            false,
        ),
        ("left wall", quads(&[LEFT_WALL]), red, false),
        ("right wall", quads(&[RIGHT_WALL]), green, false),
        ("short block", quads(&SHORT_BLOCK), white, false),
        ("tall block", quads(&TALL_BLOCK), mirror, false),
        (
            "glass ball",
            icosphere(Vec3::new(185.5, 165.0 + 70.0, 169.0), 70.0, 3),
            glass,
            true,
        ),
        ("light", light_panel(), lamp, false),
    ];
    for (name, mesh, material, smooth) in &objects {
        scene
            .add(*name, mesh, &place, *material, *smooth)
            .expect("the built-in scene is small and finite");
    }
    let (corner, edge_u, edge_v) = light_frame();
    let lights = vec![Light::Rect {
        corner,
        edge_u,
        edge_v,
        radiance: light_radiance(),
        samples: 16,
    }];
    let camera = Camera {
        position: Vec3::new(278.0, 273.0, -800.0),
        look_at: Vec3::new(278.0, 273.0, 0.0),
        up: Vec3::Y,
        // The published 35 mm focal length on a 25 mm film: 2·atan(12.5/35).
        fov_y_degrees: 2.0 * (12.5f32 / 35.0).atan().to_degrees(),
    };
    let settings = RenderSettings {
        width: 512,
        height: 512,
        spp: 4,
        max_depth: 6,
        background: Vec3::ZERO,
        ambient: Vec3::splat(0.06),
    };
    scene.finish(materials, camera, lights, settings)
}

/// The light's corner and edges, `edge_u × edge_v` pointing down into the box.
fn light_frame() -> (Vec3, Vec3, Vec3) {
    (
        Vec3::from(LIGHT_CORNER),
        Vec3::new(0.0, 0.0, LIGHT_SIZE[1]),
        Vec3::new(-LIGHT_SIZE[0], 0.0, 0.0),
    )
}

fn light_radiance() -> Vec3 {
    Vec3::new(42.0, 36.0, 26.0)
}

/// The light's visible panel (two triangles), so that the camera and mirrors see it.
fn light_panel() -> TriangleMesh {
    let (c, u, v) = light_frame();
    TriangleMesh::new(vec![c, c + u, c + u + v, c + v], vec![[0, 1, 2], [0, 2, 3]])
        .expect("the light panel is finite")
}
