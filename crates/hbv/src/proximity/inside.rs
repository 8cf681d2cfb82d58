//! Whether a point lies inside a closed mesh.

use glam::Vec3;

use crate::all_hits::AllHits;
use crate::geometry::Ray;
use crate::query::Hit;

/// The directions of the inside tests' rays: no axis-aligned component and no small rational
/// ratios between components, so that rays from the points of a grid-aligned or symmetric mesh
/// rarely pass exactly through an edge or vertex (where the exact, slower edge signs decide).
/// Exactness does not depend on them. [`contains`] casts the first.
const RAY_DIRECTIONS: [Vec3; 3] = [
    Vec3::new(0.538_953_8, 0.691_244_6, -0.481_582_5),
    Vec3::new(-0.772_313_3, 0.237_142_4, 0.589_337_3),
    Vec3::new(0.178_893_5, -0.863_739_3, -0.471_213_7),
];

/// Whether `point` lies inside the closed mesh that `accel` traces: the parity of the number of
/// triangles a ray from the point (over `[0, +inf]`) crosses, counted in one all-hits traversal
/// (Jordan's theorem: odd means inside).
///
/// One ray is exact: the all-hits queries count a ray through an edge or vertex as the ray
/// moved by an infinitesimal amount would cross there (exact edge signs and the half-open
/// rule, [`EdgeRule::HalfOpen`]), so the count has the parity of a ray in general position.
/// (Until the edge signs were exact, a ray through an edge could count both triangles there,
/// and the test took the majority of three rays: twice the traversals.) The generalized
/// winding number (Jacobson et al. 2013) is exact even on open meshes, but costs a sum over
/// all triangles per point (or a hierarchical approximation, Barill et al. 2018), while a ray
/// costs a traversal. The mesh must be closed (every edge shared by an even number of
/// triangles: [`TriangleMesh::is_closed`](crate::TriangleMesh::is_closed)); points on the
/// surface may be reported either way. A point with a NaN or infinite coordinate is outside.
///
/// [`EdgeRule::HalfOpen`]: crate::geometry::EdgeRule::HalfOpen
pub fn contains<A: AllHits + ?Sized>(accel: &A, point: Vec3) -> bool {
    contains_along(accel, point, RAY_DIRECTIONS[0])
}

/// [`contains`] by a ray of the given direction: the parity of its crossings. Any direction
/// gives the same answer for a point off the surface of a closed mesh; a zero, NaN or
/// infinite direction (no ray) says outside.
pub fn contains_along<A: AllHits + ?Sized>(accel: &A, point: Vec3, direction: Vec3) -> bool {
    odd_crossings(accel, point, direction, &mut Vec::new())
}

/// Whether `point` is inside by the majority of three rays' parities (the third cast only when
/// the first two disagree): for meshes that are not closed, where inside is not defined and
/// one ray's answer depends on whether it escapes through a hole. Two rays of three agree
/// with the surrounding surface more often than one: a point in a room with a missing wall
/// is inside unless two of its rays leave through the gap. On a closed mesh it answers as
/// [`contains`] does, at twice the cost.
pub fn contains_by_majority<A: AllHits + ?Sized>(accel: &A, point: Vec3) -> bool {
    // One list of hits for the three rays.
    let mut hits = Vec::new();
    let mut vote = |direction| odd_crossings(accel, point, direction, &mut hits);
    let (first, second) = (vote(RAY_DIRECTIONS[0]), vote(RAY_DIRECTIONS[1]));
    if first == second {
        first
    } else {
        vote(RAY_DIRECTIONS[2])
    }
}

/// Whether the ray from `point` along `direction` crosses the surface an odd number of times
/// (false for no valid ray), `hits` holding its hits.
fn odd_crossings<A: AllHits + ?Sized>(
    accel: &A,
    point: Vec3,
    direction: Vec3,
    hits: &mut Vec<Hit>,
) -> bool {
    let ray = Ray::new(point, direction);
    if !(point.is_finite() && ray.is_valid()) {
        return false;
    }
    accel.all_hits(&Ray::new(point, reaching_every_crossing(direction)), hits);
    hits.len() % 2 == 1
}

/// `direction` (valid) scaled by the power of two that brings its largest component into
/// `[4, 8)`: the same ray (the scaling is exact, and so is every decision of the ray's tests),
/// whose crossings all lie at `t` below `f32::MAX`. A crossing lies on the mesh, within
/// [`MAX_COORDINATE`](crate::mesh::MAX_COORDINATE) = `f32::MAX / 2` of the origin on each axis,
/// and the point within `f32::MAX`: at most `√3 · 1.5 · f32::MAX` away, which `|d| ≥ 4` brings to
/// `t ≤ 0.65 f32::MAX`. (A unit direction met a sphere of radius 1.7e38 at `t` beyond
/// `f32::MAX`, where no f32 `t` exists, and lost the crossing: points outside it were inside.)
fn reaching_every_crossing(direction: Vec3) -> Vec3 {
    let largest = direction.abs().max_element();
    // The largest component of a valid direction is a normal float: 2^exponent ≤ it < 2^(exponent + 1).
    let exponent = (largest.to_bits() >> 23) as i32 - 127;
    let shift = 2 - exponent;
    // Two factors, each a power of two within f32's range.
    direction * 2f32.powi(shift / 2) * 2f32.powi(shift - shift / 2)
}
