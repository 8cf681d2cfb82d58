//! Whether a mesh encloses a volume: its open edges.
//!
//! An inside test by ray parity (`proximity::inside`: a point is inside when a ray from it
//! crosses the surface an odd number of times) answers the same for every ray exactly when every
//! edge of the surface is shared by an even number of triangles: the surface is then a cycle
//! modulo 2, and the parity of a path's crossings depends only on its ends (the Jordan–Brouwer
//! separation theorem in its mod-2 form). An edge of an odd number of triangles is **open**: the
//! rim of a hole (one triangle), or a fin left on a closed part (three). Around an open edge
//! two rays from the same point may disagree, and "inside" is not defined.
//!
//! Edges are compared by their ends' **positions**, not their vertex indices: files often split
//! a vertex where normals or texture coordinates change (OBJ and glTF seams, a cube's 24
//! corners), and such a mesh is closed although its indices do not say so. A T-junction (a
//! vertex in the middle of another triangle's edge) counts as open, as it does for an indexed
//! test: the long edge has one triangle, each half another. Degenerate triangles are left out,
//! as the accelerators leave them out (they are never crossed).

use rayon::prelude::*;

use super::TriangleMesh;

impl TriangleMesh {
    /// The number of open edges: edges, with vertices identified by position, shared by an odd
    /// number of the mesh's non-degenerate triangles (module notes). Zero for a closed mesh,
    /// for which [`crate::proximity::contains`] is defined.
    ///
    /// Sorts the vertices by position and the triangles' edges by their ends, in parallel:
    /// O(F log F) for F triangles (about 0.1 s for a million).
    pub fn open_edge_count(&self) -> usize {
        let id = position_ids(self);
        let mut edges: Vec<u64> = (0..self.triangle_count())
            .into_par_iter()
            .filter(|&f| !self.triangle(f).is_degenerate())
            .flat_map_iter(|f| {
                let [a, b, c] = self.indices()[f].map(|v| id[v as usize]);
                [(a, b), (b, c), (c, a)]
                    .map(|(x, y)| u64::from(x.min(y)) << 32 | u64::from(x.max(y)))
            })
            .collect();
        edges.par_sort_unstable();
        edges
            .chunk_by(|x, y| x == y)
            .filter(|run| run.len() % 2 == 1)
            .count()
    }

    /// Whether every edge is shared by an even number of triangles ([`Self::open_edge_count`]
    /// is zero): the mesh bounds a volume, and inside tests are defined.
    pub fn is_closed(&self) -> bool {
        self.open_edge_count() == 0
    }
}

/// For each vertex, an id shared by every vertex at the same position (the smallest such
/// index). Coordinates are compared as bits after `+ 0.0`, which turns −0 into +0 (positions
/// are finite, checked on construction).
fn position_ids(mesh: &TriangleMesh) -> Vec<u32> {
    let positions = mesh.positions();
    let mut keyed: Vec<([u32; 3], u32)> = (0..positions.len())
        .into_par_iter()
        .map(|v| ((positions[v] + 0.0).to_array().map(f32::to_bits), v as u32))
        .collect();
    keyed.par_sort_unstable();
    let mut id = vec![0u32; positions.len()];
    for run in keyed.chunk_by(|x, y| x.0 == y.0) {
        // Sorted by index within a run of equal keys: the first is the smallest.
        for &(_, v) in run {
            id[v as usize] = run[0].1;
        }
    }
    id
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::procedural::{icosphere, torus};
    use glam::Vec3;
    use proptest::prelude::*;
    use std::collections::HashMap;

    /// The reference: every non-degenerate triangle's edges, ends as position bits (−0 as +0),
    /// counted in a map; the open edges are those counted an odd number of times.
    fn open_edges_by_map(mesh: &TriangleMesh) -> usize {
        let key = |v: u32| {
            (mesh.positions()[v as usize] + 0.0)
                .to_array()
                .map(f32::to_bits)
        };
        let mut count: HashMap<([u32; 3], [u32; 3]), usize> = HashMap::new();
        for (f, &[a, b, c]) in mesh.indices().iter().enumerate() {
            if mesh.triangle(f).is_degenerate() {
                continue;
            }
            for (x, y) in [(a, b), (b, c), (c, a)] {
                let (x, y) = (key(x), key(y));
                *count.entry((x.min(y), x.max(y))).or_default() += 1;
            }
        }
        count.values().filter(|&&n| n % 2 == 1).count()
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(256))]

        /// Random faces over a small lattice (so that edges are shared, by several triangles or
        /// none, and some triangles are degenerate), vertices duplicated at random and some
        /// written with negative zeros: the count equals the map's.
        #[test]
        fn open_edges_match_a_map_of_edges(
            faces in prop::collection::vec([0u32..12, 0u32..12, 0u32..12], 0..60),
            copies in prop::collection::vec(0u32..3, 60 * 3),
        ) {
            // 12 lattice points (−1, 0 or 1 on x; 0 or 1 on y and z, some zeros negative), each
            // present three times as different vertices.
            let lattice: Vec<Vec3> = (0..12)
                .map(|i| {
                    let zero = if i % 5 == 0 { -0.0 } else { 0.0 };
                    let pick = |bit: u32| if i & bit != 0 { 1.0 } else { zero };
                    Vec3::new((i % 3) as f32 - 1.0, pick(4), pick(8))
                })
                .collect();
            let positions: Vec<Vec3> = (0..3).flat_map(|_| lattice.iter().copied()).collect();
            let indices: Vec<[u32; 3]> = faces
                .iter()
                .enumerate()
                .map(|(f, t)| {
                    let mut k = 0;
                    t.map(|v| {
                        k += 1;
                        v + 12 * copies[3 * f + k - 1]
                    })
                })
                .collect();
            let mesh = TriangleMesh::new(positions, indices).unwrap();
            prop_assert_eq!(mesh.open_edge_count(), open_edges_by_map(&mesh));
        }

        /// A closed mesh stays closed with its vertices split per corner and its faces
        /// shuffled; removing triangles opens exactly the edges the map says.
        #[test]
        fn closed_meshes_split_and_holed(seed in any::<u64>(), remove in 0usize..6) {
            use rand::{seq::SliceRandom, SeedableRng};
            let sphere = icosphere(Vec3::new(0.3, -0.2, 0.1), 1.5, 1);
            let mut corners: Vec<Vec3> = Vec::new();
            let mut faces: Vec<[u32; 3]> = Vec::new();
            for t in sphere.indices() {
                let base = corners.len() as u32;
                corners.extend(t.map(|v| sphere.positions()[v as usize]));
                faces.push([base, base + 1, base + 2]);
            }
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
            faces.shuffle(&mut rng);
            let split = TriangleMesh::new(corners.clone(), faces.clone()).unwrap();
            prop_assert!(split.is_closed());
            faces.truncate(faces.len() - remove);
            let holed = TriangleMesh::new(corners, faces).unwrap();
            prop_assert_eq!(holed.open_edge_count(), open_edges_by_map(&holed));
            prop_assert_eq!(holed.is_closed(), remove == 0);
        }
    }

    fn mesh(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> TriangleMesh {
        let positions = positions.iter().map(|&p| Vec3::from(p)).collect();
        TriangleMesh::new(positions, faces.to_vec()).unwrap()
    }

    /// A unit cube, each face with its own four corners (24 vertices, as files with per-face
    /// normals have), optionally without some of its faces.
    fn split_cube(without: &[usize]) -> TriangleMesh {
        let corner = |i: u32| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32];
        let quads: [[u32; 4]; 6] = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let (mut positions, mut faces) = (Vec::new(), Vec::new());
        for (q, quad) in quads.iter().enumerate() {
            if without.contains(&q) {
                continue;
            }
            let base = positions.len() as u32;
            positions.extend(quad.map(corner));
            faces.push([base, base + 1, base + 2]);
            faces.push([base, base + 2, base + 3]);
        }
        mesh(&positions, &faces)
    }

    #[test]
    fn closed_meshes_have_no_open_edges() {
        assert_eq!(icosphere(Vec3::ZERO, 1.0, 2).open_edge_count(), 0);
        assert!(torus(Vec3::ZERO, 2.0, 0.5, 16, 8).is_closed());
    }

    #[test]
    fn vertices_split_at_seams_are_joined_by_position() {
        let cube = split_cube(&[]);
        assert_eq!(cube.positions().len(), 24);
        assert!(cube.is_closed());
    }

    #[test]
    fn holes_and_loose_triangles_are_open() {
        // One face removed: its square rim (4 edges) is open; the diagonals of the other faces
        // are shared by their two triangles.
        assert_eq!(split_cube(&[2]).open_edge_count(), 4);
        // Two opposite faces removed: two rims.
        assert_eq!(split_cube(&[0, 1]).open_edge_count(), 8);
        let triangle = mesh(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]);
        assert_eq!(triangle.open_edge_count(), 3);
        assert!(!triangle.is_closed());
    }

    #[test]
    fn even_sharing_is_closed_and_odd_is_open() {
        let cube = split_cube(&[]);
        let corners = || cube.positions().iter().map(|p| p.to_array());
        // Two cubes touching along an edge, the line x = y = 1: four triangles there.
        let mut positions: Vec<[f32; 3]> = corners().collect();
        positions.extend(corners().map(|[x, y, z]| [x + 1.0, y + 1.0, z]));
        let mut faces = cube.indices().to_vec();
        faces.extend(cube.indices().iter().map(|f| f.map(|v| v + 24)));
        assert!(
            mesh(&positions, &faces).is_closed(),
            "two cubes touching along an edge"
        );
        // A fin: a triangle on the cube edge from vertex 0, (0, 0, 0), to vertex 1, (0, 1, 0),
        // which then has three triangles, its other two edges one each.
        let mut positions: Vec<[f32; 3]> = corners().collect();
        assert_eq!((positions[0], positions[1]), ([0.0; 3], [0.0, 1.0, 0.0]));
        positions.push([-1.0, 0.5, -1.0]);
        let mut faces = cube.indices().to_vec();
        faces.push([0, 1, 24]);
        assert_eq!(mesh(&positions, &faces).open_edge_count(), 3);
    }

    #[test]
    fn degenerate_triangles_and_signed_zeros_do_not_open_a_mesh() {
        let cube = split_cube(&[]);
        let mut positions: Vec<[f32; 3]> = cube.positions().iter().map(|p| p.to_array()).collect();
        // One face's copy of the corner (0, 0, 0) written with negative zeros: the same point.
        assert_eq!(positions[0], [0.0; 3]);
        positions[0] = [-0.0, 0.0, -0.0];
        // A collapsed triangle, and a collinear one along the edge from vertex 0 to vertex 3,
        // (1, 0, 0): neither can be crossed, and neither opens an edge.
        assert_eq!(positions[3], [1.0, 0.0, 0.0]);
        positions.push([0.5, 0.0, 0.0]);
        let mut faces = cube.indices().to_vec();
        faces.extend([[0, 1, 1], [0, 24, 3]]);
        let m = mesh(&positions, &faces);
        assert_eq!(m.degenerate_count(), 2);
        assert!(m.is_closed(), "{} open edges", m.open_edge_count());
    }

    #[test]
    fn a_t_junction_counts_as_open() {
        // Two triangles on one side of the x axis's segment [0, 2], two on the other split at
        // x = 1: the long edge has one triangle, each half one. (A flat, open patch: its outer
        // rim is open too; the junction adds three open edges.)
        let positions = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, -1.0, 0.0],
        ];
        let with_junction = mesh(&positions, &[[0, 1, 2], [0, 4, 3], [3, 4, 1]]);
        let without = mesh(&positions, &[[0, 1, 2], [0, 4, 1]]);
        assert_eq!(without.open_edge_count(), 4);
        assert_eq!(with_junction.open_edge_count(), 4 + 3);
    }
}
