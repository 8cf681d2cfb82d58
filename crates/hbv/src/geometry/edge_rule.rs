//! Which triangles a ray hits when it passes exactly through an edge or a vertex.

/// What the watertight test does with a ray that passes exactly through an edge's line: an
/// edge function that is exactly zero, decided by exact arithmetic (see
/// [`Triangle::intersect_by`](crate::geometry::Triangle::intersect_by)). Rays anywhere else are
/// decided alike under either rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeRule {
    /// Edges and vertices belong to every triangle that has them: a ray through a shared edge
    /// hits both triangles, and a ray that only touches a surface (grazing a silhouette edge,
    /// starting on an edge) hits it. The rule of the closest- and any-hit queries, where a touch
    /// is a hit and a crossing reported twice costs nothing.
    Closed,
    /// Each zero edge function takes the sign it would have if the ray were moved by an
    /// infinitesimal amount in a fixed direction of its own frame (simulation of simplicity): a
    /// ray through a shared edge or vertex where it crosses a surface hits exactly one of the
    /// triangles there, and one that only touches it hits none or two. Counts of hits are then
    /// counts of crossings, and their parity is right on closed meshes: the rule of
    /// [`AllHits`](crate::AllHits) (counts, every hit along a ray, inside tests).
    HalfOpen,
}
