//! The reference every nearest-point search is tested against: each triangle decided in f64,
//! the nearest kept.

use glam::DVec3;

use super::answers::ClosestPoint;
use super::point_triangle::closest_point_on_triangle;
use crate::mesh::TriangleMesh;

/// The nearest surface point by testing every non-degenerate triangle in f64: the reference of
/// every [`NearestPointSearch`](super::NearestPointSearch) (same answer, same tie rule: smallest
/// face id among equal distances).
pub fn closest_point_brute_force(mesh: &TriangleMesh, p: DVec3) -> Option<ClosestPoint> {
    if !p.is_finite() {
        return None;
    }
    let mut best: Option<ClosestPoint> = None;
    let mut best_d2 = f64::INFINITY;
    for (prim, t) in mesh.triangles().enumerate() {
        if t.is_degenerate() {
            continue;
        }
        let q = closest_point_on_triangle(p, t.p0.as_dvec3(), t.p1.as_dvec3(), t.p2.as_dvec3());
        let d2 = (p - q.point).length_squared();
        if d2 < best_d2 {
            best_d2 = d2;
            best = Some(ClosestPoint {
                point: q.point,
                distance: d2.sqrt(),
                prim: prim as u32,
                u: q.u,
                v: q.v,
            });
        }
    }
    best
}
