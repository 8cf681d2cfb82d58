//! Whether a point lies inside a closed mesh.

use glam::Vec3;

use crate::all_hits::AllHits;
use crate::geometry::Ray;

/// The directions of the three votes: unit vectors with no axis-aligned component and no small
/// rational ratios between components, so that a ray from a point of a grid-aligned or
/// symmetric mesh is unlikely to run exactly through an edge or vertex.
const VOTE_DIRECTIONS: [Vec3; 3] = [
    Vec3::new(0.538_953_8, 0.691_244_6, -0.481_582_5),
    Vec3::new(-0.772_313_3, 0.237_142_4, 0.589_337_3),
    Vec3::new(0.178_893_5, -0.863_739_3, -0.471_213_7),
];

/// Whether `point` lies inside the closed mesh that `accel` traces: the majority of three parity
/// votes (the third cast only when the first two disagree). Each vote casts a ray from the point (over `[0, +inf]`) and counts every triangle it
/// crosses in one all-hits traversal (Jordan's theorem: odd means inside).
///
/// Why a vote of rays rather than one ray or a winding number: one ray is wrong when it passes
/// exactly through an edge or vertex, where the watertight test reports every triangle sharing
/// it (2 or more crossings for one); such a ray is rare for a direction fixed in advance, and
/// a wrong answer needs two of the three independent rays to be so unlucky. The generalized
/// winding number (Jacobson et al. 2013) is exact even on open meshes, but costs a sum over all
/// triangles per point (or a hierarchical approximation, Barill et al. 2018), while a ray costs a
/// traversal. The mesh must be closed (every edge shared by an even number of triangles:
/// [`TriangleMesh::is_closed`](crate::TriangleMesh::is_closed)); points on the surface
/// may be reported either way. A point with a NaN or infinite coordinate is outside.
pub fn contains<A: AllHits + ?Sized>(accel: &A, point: Vec3) -> bool {
    if !point.is_finite() {
        return false;
    }
    let mut hits = Vec::new();
    let mut votes_inside = |direction: Vec3| {
        accel.all_hits(&Ray::new(point, direction), &mut hits);
        hits.len() % 2 == 1
    };
    let [first, second, third] = VOTE_DIRECTIONS;
    let (first, second) = (votes_inside(first), votes_inside(second));
    // Two agreeing votes are already a majority: the third ray is cast only to break a tie.
    if first == second {
        first
    } else {
        votes_inside(third)
    }
}
