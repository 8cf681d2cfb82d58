//! The branch-and-bound search of a [`ClosestPointTree`] (its notes give the bounds, Larsen et
//! al. 1999 and Ericson §6.5): nodes' children bounded eight at a time, the nearest child
//! searched next; in a leaf, each packet's enclosure bounds, then the exact f64 routine for the
//! triangles they do not reject, four side by side where two or more of a half packet are left.
//! Also the same walk with a fixed radius, for the candidate grid's lists.

use glam::DVec3;

use super::answers::ClosestPoint;
use super::box_bound::{prune_threshold, rounding_margin, PointBracket};
use super::candidate_grid::NearestTriangles;
use super::closest_point_tree::ClosestPointTree;
use super::enclosure_packet::LANES;
use super::point_triangle::{
    closest_point_on_flagged_triangle, closest_point_on_sliver, TrianglePoint,
};
use super::point_triangle_lanes::F64_LANES;
use super::search_lanes::SearchLanes;
use super::search_tally::Tally;
use super::search_tree::WIDTH;

/// One pending child of the search: its lower bound, and a node index (`triangles == 0`) or a
/// leaf's first packet and triangle count.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pending {
    bound: f32,
    child: u32,
    triangles: u32,
}

/// The best triangle so far of one search.
struct Best {
    /// The nearest point so far, its triangle's face id and local id (`LANES × packet + lane`).
    found: Option<(TrianglePoint, u32, u32)>,
    d2: f64,
    /// [`prune_threshold`] of `d2`.
    threshold: f32,
    /// The rounding margin of [`prune_threshold`] for this query.
    delta: f64,
}

impl Best {
    /// Whether a triangle `prim` at computed squared distance `d2` replaces the best so far:
    /// nearer, or as near with a smaller face id (the brute force's tie rule).
    #[inline(always)]
    fn is_beaten_by(&self, d2: f64, prim: u32) -> bool {
        d2 < self.d2 || (d2 == self.d2 && self.found.is_some_and(|(_, b, _)| prim < b))
    }

    /// Makes `q` on triangle `prim` (local id `local`), at squared distance `d2`, the best.
    #[inline(always)]
    fn record(&mut self, q: TrianglePoint, d2: f64, prim: u32, local: u32) {
        self.d2 = d2;
        self.threshold = prune_threshold(d2, self.delta);
        self.found = Some((q, prim, local));
    }
}

impl ClosestPointTree {
    /// The branch-and-bound search, starting from triangle `seed` (`LANES × packet + lane`) as the
    /// best so far when given; returns the answer and its triangle's `LANES × packet + lane`.
    /// `stack` is scratch space, reused between searches.
    #[inline(always)]
    pub(super) fn search<M: SearchLanes>(
        &self,
        p: DVec3,
        seed: Option<u32>,
        stack: &mut Vec<Pending>,
        tally: &mut impl Tally,
    ) -> Option<(ClosestPoint, u32)> {
        let tree = &self.tree;
        if tree.nodes.is_empty() || !p.is_finite() {
            return None;
        }
        let bracket = PointBracket::new(p);
        let mut best = Best {
            found: None,
            d2: f64::INFINITY,
            threshold: f32::INFINITY,
            delta: rounding_margin(p, tree.mesh_scale),
        };
        if let Some(local) = seed {
            tally.exact();
            self.consider(p, local, &mut best);
        }
        stack.clear();
        // The child to search next: the nearest of the last node's, taken without a trip
        // through the stack.
        let mut next = Some(Pending {
            bound: 0.0,
            child: 0,
            triangles: 0,
        });
        while let Some(pending) = next.take().or_else(|| stack.pop()) {
            if pending.bound > best.threshold {
                continue;
            }
            if pending.triangles > 0 {
                self.search_leaf::<M>(p, &bracket, pending, seed, &mut best, tally);
                continue;
            }
            tally.node();
            let node = &tree.nodes[pending.child as usize];
            let bounds = node.distance_squared_lower_bounds(&bracket);
            let mut within = M::within(&bounds, best.threshold);
            // The children within the threshold: the nearest is searched next, the others
            // pushed in slot order. (Sorted farthest first, the search visited the same nodes
            // and packets on the bunny for 140 more instructions per query: 0–6 % slower on
            // the bunny and spot.)
            let mut near = [Pending {
                bound: 0.0,
                child: 0,
                triangles: 0,
            }; WIDTH];
            let mut count = 0;
            let mut nearest = 0;
            while within != 0 {
                let k = within.trailing_zeros() as usize;
                within &= within - 1;
                let entry = Pending {
                    bound: bounds[k],
                    child: node.child[k],
                    triangles: node.triangles[k],
                };
                nearest = if entry.bound < near[nearest].bound {
                    count
                } else {
                    nearest
                };
                near[count] = entry;
                count += 1;
            }
            if count > 0 {
                near.swap(nearest, count - 1);
                // `extend` of a copied slice iterator: one capacity check, no `memmove` call
                // (`extend_from_slice` made one, a tenth of the time here).
                stack.extend(near[..count - 1].iter().copied());
                next = Some(near[count - 1]);
            }
        }
        // One square root per search, for the answer only.
        best.found.map(|(q, prim, local)| {
            let answer = ClosestPoint {
                point: q.point,
                distance: best.d2.sqrt(),
                prim,
                u: q.u,
                v: q.v,
            };
            (answer, local)
        })
    }

    /// Tests the triangles of one leaf: each packet's bounds first, the exact routine
    /// for those within the threshold, but the search's seed (decided first, and always within
    /// the threshold of its own distance: on spot 5.6 → 5.0 exact tests per query).
    #[inline(always)]
    fn search_leaf<M: SearchLanes>(
        &self,
        p: DVec3,
        bracket: &PointBracket,
        leaf: Pending,
        seed: Option<u32>,
        best: &mut Best,
        tally: &mut impl Tally,
    ) {
        let (seed_packet, seed_lane) = match seed {
            Some(local) => (local as usize / LANES, local as usize % LANES),
            None => (usize::MAX, 0),
        };
        let mut left = leaf.triangles as usize;
        let mut packet = leaf.child as usize;
        while left > 0 {
            tally.packet();
            let bounds = self.tree.packets[packet].distance_squared_lower_bounds(bracket);
            // Not `bound <= threshold`: a NaN bound must not prune.
            let mut within = M::not_beyond(&bounds, best.threshold);
            // Lanes past the leaf's last triangle repeat lane 0.
            within &= (1u32 << left.min(LANES)) - 1;
            if packet == seed_packet {
                within &= !(1u32 << seed_lane);
            }
            // A half of the packet with two or more triangles left is decided four lanes at
            // once (`consider_half`: branch-free, where the lane-by-lane routine mispredicts
            // its Voronoi-region branches); a single one by the scalar routine. Bunny +2–5 %
            // against one lane at a time, spot and teapot within 1 %; deciding every half
            // with a triangle left four at a time: bunny a further +1 %, spot and teapot −2 %.
            for half in 0..LANES / F64_LANES {
                let mut lanes = (within >> (half * F64_LANES)) & ((1 << F64_LANES) - 1);
                if lanes.count_ones() >= 2 {
                    for _ in 0..F64_LANES {
                        tally.exact();
                    }
                    self.consider_half::<M>(p, packet, half, best);
                    continue;
                }
                while lanes != 0 {
                    let lane = half * F64_LANES + lanes.trailing_zeros() as usize;
                    lanes &= lanes - 1;
                    // The threshold may have dropped since the bounds were compared.
                    if bounds[lane] <= best.threshold || bounds[lane].is_nan() {
                        tally.exact();
                        self.consider(p, (packet * LANES + lane) as u32, best);
                    }
                }
            }
            left = left.saturating_sub(LANES);
            packet += 1;
        }
    }

    /// Decides the four triangles of half `half` of packet `packet` side by side
    /// (module `point_triangle_lanes`: the same bits as [`ClosestPointTree::consider`] lane by
    /// lane) and keeps each as `consider` would. Lanes the bounds pruned, past the leaf's end
    /// (repeats of lane 0) or the seed's are decided too: an exact answer for a triangle of the
    /// mesh never makes the result wrong.
    #[inline(always)]
    fn consider_half<M: SearchLanes>(&self, p: DVec3, packet: usize, half: usize, best: &mut Best) {
        let data = &self.tree.packets[packet];
        let mut found = M::closest_points_on_half(p, &data.vertex, half);
        // Slivers (rare) are decided again by the scalar routine, whose sliver path the lanes
        // do not have.
        let slivers = data.slivers >> (half * F64_LANES) & ((1 << F64_LANES) - 1);
        if slivers != 0 {
            for l in 0..F64_LANES {
                if slivers >> l & 1 == 1 {
                    let [a, b, c] = data.triangle(half * F64_LANES + l);
                    let q = closest_point_on_sliver(p, a, b, c);
                    for axis in 0..3 {
                        found.point[axis][l] = q.point[axis];
                    }
                    found.u[l] = q.u;
                    found.v[l] = q.v;
                    found.distance_squared[l] = (p - q.point).length_squared();
                }
            }
        }
        for l in 0..F64_LANES {
            let lane = half * F64_LANES + l;
            let (d2, prim) = (found.distance_squared[l], data.prim[lane]);
            if best.is_beaten_by(d2, prim) {
                let q = TrianglePoint {
                    point: DVec3::new(found.point[0][l], found.point[1][l], found.point[2][l]),
                    u: found.u[l],
                    v: found.v[l],
                };
                best.record(q, d2, prim, (packet * LANES + lane) as u32);
            }
        }
    }

    /// Decides triangle `local` (`LANES × packet + lane`) in f64 and keeps it if it is nearer than
    /// the best, or as near with a smaller face id.
    #[inline(always)]
    fn consider(&self, p: DVec3, local: u32, best: &mut Best) {
        let packet = &self.tree.packets[local as usize / LANES];
        let lane = local as usize % LANES;
        let [a, b, c] = packet.triangle(lane);
        let prim = packet.prim[lane];
        let q = closest_point_on_flagged_triangle(p, a, b, c, packet.slivers >> lane & 1 == 1);
        let d2 = (p - q.point).length_squared();
        if best.is_beaten_by(d2, prim) {
            best.record(q, d2, prim, local);
        }
    }

    /// Every triangle whose computed squared distance from `p` is at most `radius_squared`,
    /// `None` when more than `limit`: the search's walk with a fixed threshold
    /// (`prune_threshold(radius_squared, δ)`, under which no triangle of a pruned box can have a
    /// computed distance within the radius).
    pub(super) fn triangles_within(
        &self,
        p: DVec3,
        radius_squared: f64,
        limit: usize,
    ) -> Option<Vec<u32>> {
        let tree = &self.tree;
        let mut found = Vec::new();
        if tree.nodes.is_empty() || !p.is_finite() {
            return Some(found);
        }
        let bracket = PointBracket::new(p);
        let threshold = prune_threshold(radius_squared, rounding_margin(p, tree.mesh_scale));
        let mut stack = vec![(0u32, 0u32)];
        while let Some((child, triangles)) = stack.pop() {
            if triangles > 0 {
                // Each packet's bounds first (as the search's leaves): the exact routine only
                // for triangles that may be within the radius.
                for k in 0..triangles.div_ceil(LANES as u32) {
                    let packet = child + k;
                    let bounds =
                        tree.packets[packet as usize].distance_squared_lower_bounds(&bracket);
                    let lanes = (triangles - k * LANES as u32).min(LANES as u32) as usize;
                    for (lane, &bound) in bounds.iter().enumerate().take(lanes) {
                        // Not `bound <= threshold`: a NaN bound must not prune.
                        if bound > threshold {
                            continue;
                        }
                        let local = packet * LANES as u32 + lane as u32;
                        if self.distance_squared(p, local) <= radius_squared {
                            found.push(local);
                            if found.len() > limit {
                                return None;
                            }
                        }
                    }
                }
                continue;
            }
            let node = &tree.nodes[child as usize];
            let bounds = node.distance_squared_lower_bounds(&bracket);
            for (k, &bound) in bounds.iter().enumerate() {
                // Empty slots have NaN bounds and fail the test.
                if bound <= threshold {
                    stack.push((node.child[k], node.triangles[k]));
                }
            }
        }
        Some(found)
    }
}
