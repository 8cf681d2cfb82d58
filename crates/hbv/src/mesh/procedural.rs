//! Meshes made in code: closed test surfaces and the built-in default scene.
//!
//! Every mesh here is indexed with shared vertices, so closed surfaces are closed exactly (the
//! watertightness tests rely on it), and every function is deterministic.

use std::f32::consts::{PI, TAU};

use glam::{Mat3, Vec3};

use super::TriangleMesh;

/// Accumulates positions and triangles of several parts into one mesh.
#[derive(Default)]
struct MeshParts {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

impl MeshParts {
    fn append(&mut self, mesh: &TriangleMesh, transform: impl Fn(Vec3) -> Vec3) {
        let base = self.positions.len() as u32;
        self.positions
            .extend(mesh.positions().iter().map(|&p| transform(p)));
        self.indices.extend(
            mesh.indices()
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    fn finish(self) -> TriangleMesh {
        TriangleMesh::new(self.positions, self.indices)
            .expect("procedural meshes have finite positions and valid indices")
    }
}

/// A sphere made by subdividing an icosahedron `subdivisions` times and projecting onto the
/// sphere: `20 · 4^subdivisions` triangles, closed, consistently wound outwards.
pub fn icosphere(center: Vec3, radius: f32, subdivisions: u32) -> TriangleMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = (positions[a as usize] + positions[b as usize]).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    for p in &mut positions {
        *p = center + radius * *p;
    }
    TriangleMesh::new(positions, faces).expect("icosphere is valid")
}

/// A torus around the z axis with the given major and minor radii, tessellated into a
/// `major_segments × minor_segments` grid of quads (two triangles each), closed.
pub fn torus(
    center: Vec3,
    major_radius: f32,
    minor_radius: f32,
    major_segments: u32,
    minor_segments: u32,
) -> TriangleMesh {
    let (m, n) = (major_segments.max(3), minor_segments.max(3));
    let mut positions = Vec::with_capacity((m * n) as usize);
    for i in 0..m {
        let phi = TAU * i as f32 / m as f32;
        for j in 0..n {
            let theta = TAU * j as f32 / n as f32;
            let r = major_radius + minor_radius * theta.cos();
            positions
                .push(center + Vec3::new(r * phi.cos(), r * phi.sin(), minor_radius * theta.sin()));
        }
    }
    let id = |i: u32, j: u32| (i % m) * n + (j % n);
    let mut faces = Vec::with_capacity((2 * m * n) as usize);
    for i in 0..m {
        for j in 0..n {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    TriangleMesh::new(positions, faces).expect("torus is valid")
}

/// A flat rectangle in the plane `z = height`, `[-half, half]²`, split into `cells²` quads.
pub fn ground_plane(half: f32, height: f32, cells: u32) -> TriangleMesh {
    let k = cells.max(1);
    let mut positions = Vec::new();
    for i in 0..=k {
        for j in 0..=k {
            let x = -half + 2.0 * half * i as f32 / k as f32;
            let y = -half + 2.0 * half * j as f32 / k as f32;
            positions.push(Vec3::new(x, y, height));
        }
    }
    let id = |i: u32, j: u32| i * (k + 1) + j;
    let mut faces = Vec::new();
    for i in 0..k {
        for j in 0..k {
            faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriangleMesh::new(positions, faces).expect("plane is valid")
}

/// Unit right triangles `(c, c + x, c + y)`, one for each corner `c`, in order: small hand-made
/// scenes for builder tests.
pub fn unit_triangles_at(corners: &[Vec3]) -> TriangleMesh {
    let positions = corners
        .iter()
        .flat_map(|&c| [c, c + Vec3::X, c + Vec3::Y])
        .collect();
    let indices = (0..corners.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    TriangleMesh::new(positions, indices).expect("finite corners give a valid mesh")
}

/// The built-in scene that `hbv` uses when no mesh is given: a ground plane with a ring of
/// tori and icospheres of varied size and tessellation, about `detail²` · 8,000 triangles
/// (`detail = 4` gives 132,480). Objects of different scales and densities, and large
/// flat triangles beside small curved ones, make it a fair small test of a tree.
pub fn default_scene(detail: u32) -> TriangleMesh {
    let d = detail.max(1);
    let mut parts = MeshParts::default();
    parts.append(&ground_plane(10.0, 0.0, 8), |p| p);
    for k in 0..8u32 {
        let angle = TAU * k as f32 / 8.0;
        let at = Vec3::new(6.0 * angle.cos(), 6.0 * angle.sin(), 0.0);
        let size = 0.6 + 0.15 * k as f32;
        if k % 2 == 0 {
            let torus = torus(Vec3::ZERO, size, 0.3 * size, 12 * d, 6 * d);
            // Stand the torus up, facing the scene's centre.
            let rot = Mat3::from_rotation_z(angle) * Mat3::from_rotation_x(PI / 2.0);
            parts.append(&torus, |p| at + rot * p + Vec3::Z * 1.3 * size);
        } else {
            let sphere = icosphere(Vec3::ZERO, size, 1 + d.min(5) / 2 + (k % 3));
            parts.append(&sphere, |p| at + p + Vec3::Z * size);
        }
    }
    parts.append(&torus(Vec3::ZERO, 2.0, 0.5, 24 * d, 12 * d), |p| {
        p + Vec3::Z * 0.5
    });
    parts.append(
        &icosphere(Vec3::new(0.0, 0.0, 2.2), 1.0, 2 + d.min(4)),
        |p| p,
    );
    parts.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Every edge of a closed, consistently oriented mesh is used once in each direction.
    fn assert_closed(mesh: &TriangleMesh) {
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for &[a, b, c] in mesh.indices() {
            for (x, y) in [(a, b), (b, c), (c, a)] {
                *edges.entry((x, y)).or_default() += 1;
            }
        }
        for (&(x, y), &n) in &edges {
            assert_eq!(n, 1, "edge {x}-{y} used {n} times");
            assert_eq!(edges.get(&(y, x)), Some(&1), "edge {x}-{y} has no twin");
        }
    }

    #[test]
    fn icosphere_is_closed_with_expected_count() {
        let s = icosphere(Vec3::ZERO, 1.0, 2);
        assert_eq!(s.triangle_count(), 320);
        assert_eq!(s.degenerate_count(), 0);
        assert_closed(&s);
    }

    #[test]
    fn torus_is_closed() {
        let t = torus(Vec3::ZERO, 2.0, 0.5, 16, 8);
        assert_eq!(t.triangle_count(), 256);
        assert_closed(&t);
    }

    #[test]
    fn default_scene_is_deterministic_and_sized() {
        let a = default_scene(4);
        assert_eq!(a, default_scene(4));
        assert!(a.triangle_count() > 30_000, "{}", a.triangle_count());
        assert_eq!(a.degenerate_count(), 0);
    }
}
