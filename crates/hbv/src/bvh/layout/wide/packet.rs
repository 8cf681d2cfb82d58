//! Packets of coherent rays traced through the wide layout together.
//!
//! Camera rays in pixel order are nearly parallel and share an origin: one ray's path through the
//! tree is almost its neighbour's. A packet of up to [`PACKET_SIZE`] such rays walks the tree
//! once (Wald et al. 2001, "Interactive rendering with coherent ray tracing", for the idea; here
//! with wide nodes): the stack, the ordering of children and the fetch of each node are shared,
//! while each ray still tests the boxes and triangles it reaches on its own, with the kernels of
//! the single-ray traversal. Each ray's answer is therefore exactly its single-ray answer.
//!
//! A packet that misses the whole tree is rejected by one interval-arithmetic test of the root
//! box (Boulos et al. 2006, "Geometric and arithmetic culling methods for entire ray packets"),
//! conservative by construction ([`PacketBounds`]). Inside the tree, interval bounds of a packet
//! are too loose to pay (they grow with the spread of `1/d`, and with the distance); per-ray
//! tests are exact and, with SIMD across the node's children, no more expensive per ray.

use super::AvxBoxes;
use std::cmp::Ordering;

use super::{BoxKernel, DefaultBoxes, WideLayout, LEAF, LEAF_COUNT_SHIFT, LEAF_FIRST_MASK};
use crate::bvh::layout::stack::TraversalStack;
use crate::bvh::layout::wide_kernels::{BoxRay, Lanes};
use crate::geometry::{Aabb, PreparedRay, Ray};
use crate::query::{record_closer_hit, record_hit, Hit, PACKET_SIZE};
use crate::stats::Counter;

/// Directions of one packet must lie within this cosine of each other (about 8°).
const MIN_DIRECTION_COSINE: f32 = 0.99;
/// Origins of one packet must lie within this fraction of the tree's diagonal.
const MAX_ORIGIN_SPREAD: f32 = 1.0 / 64.0;

/// The ranges of a packet's ray constants, from which the box test bounds every ray's slab
/// distances at once.
///
/// For one axis, a ray's distance to a plane `p` is `(p - o) · inv`, computed in f32 as
/// `fl(fl(p - o) · inv)`. Over the packet, `o` ranges over `[o_lo, o_hi]` and `inv` over
/// `[inv_lo, inv_hi]`, all of one sign (the packet's rays share direction signs). Rounding is
/// monotonic, so every ray's distance lies between the smallest and the largest of the products
/// at the corners of those ranges:
///
/// ```text
///   inv > 0:  distance is increasing in (p - o):  near ≥ min(fl(p - o_hi) · inv_lo, fl(p - o_hi) · inv_hi)
///                                                 far  ≤ max(fl(q - o_lo) · inv_lo, fl(q - o_lo) · inv_hi)
///   inv < 0:  decreasing:                          near ≥ min over fl(p - o_lo) · {inv_lo, inv_hi}
///                                                 far  ≤ max over fl(q - o_hi) · {inv_lo, inv_hi}
/// ```
///
/// (both products are taken because `p - o` may be of either sign). The maximum over axes of a
/// lower bound is a lower bound of the maximum, and the widening of
/// [`Aabb::intersect_interval`] is monotonic; so the packet's `[near, far]`, clipped to the
/// smallest `tmin` and the largest `tmax` of its rays, contains every ray's widened interval. If
/// any ray meets the box, the packet does.
struct PacketBounds {
    /// Which side of a box (0 min, 1 max) holds the near plane on each axis (1 for negative
    /// directions).
    near_side: [usize; 3],
    /// The origin coordinate that minimizes the near distance, per axis.
    near_origin: [f32; 3],
    /// The origin coordinate that maximizes the far distance, per axis.
    far_origin: [f32; 3],
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    tmin: f32,
}

impl PacketBounds {
    /// The bounds of the valid rays in `rays` (bit `i` of `valid`), or `None` when the packet has
    /// no valid ray or is too scattered for the bounds to reject anything: direction signs that
    /// differ, directions more than about 8° apart, origins farther apart than 1/64 of the tree.
    fn new(rays: &[PreparedRay], valid: u32, tree_diagonal: f32) -> Option<Self> {
        let first = rays.get(Lanes(valid).next()?)?;
        let first_direction = first.direction.normalize();
        let mut origin_lo = first.origin;
        let mut origin_hi = first.origin;
        let mut inv_lo = first.inv_direction;
        let mut inv_hi = first.inv_direction;
        let mut tmin = first.box_tmin();
        for r in Lanes(valid).map(|i| &rays[i]) {
            let coherent = r.negative == first.negative
                && r.inv_direction.is_finite()
                && r.direction.normalize().dot(first_direction) >= MIN_DIRECTION_COSINE;
            if !coherent {
                return None;
            }
            origin_lo = origin_lo.min(r.origin);
            origin_hi = origin_hi.max(r.origin);
            inv_lo = inv_lo.min(r.inv_direction);
            inv_hi = inv_hi.max(r.inv_direction);
            tmin = tmin.min(r.box_tmin());
        }
        let spread = (origin_hi - origin_lo).max_element();
        // Rejects a NaN spread or diagonal too.
        if spread.partial_cmp(&(MAX_ORIGIN_SPREAD * tree_diagonal)) != Some(Ordering::Less) {
            return None;
        }
        let negative = first.negative;
        let pick = |axis: usize, for_near: bool| {
            // inv > 0: near uses the largest origin, far the smallest; inv < 0: the reverse.
            if negative[axis] == for_near {
                origin_lo[axis]
            } else {
                origin_hi[axis]
            }
        };
        Some(Self {
            near_side: negative.map(usize::from),
            near_origin: [0, 1, 2].map(|a| pick(a, true)),
            far_origin: [0, 1, 2].map(|a| pick(a, false)),
            inv_lo: inv_lo.to_array(),
            inv_hi: inv_hi.to_array(),
            tmin,
        })
    }

    /// Whether some ray of the packet may meet `bounds` before `tmax` (the largest `tmax` of
    /// the packet's rays): the slab test with the bounds above, widened like
    /// [`Aabb::intersect_interval`].
    // One counter indexes the axis of the planes and of the bounds alike.
    #[allow(clippy::needless_range_loop)]
    fn hits(&self, bounds: &Aabb, tmax: f32) -> bool {
        const SLACK: f32 = PreparedRay::BOX_SLACK;
        let planes = [bounds.min, bounds.max];
        let mut near = f32::NEG_INFINITY;
        let mut far = f32::INFINITY;
        for axis in 0..3 {
            let side = self.near_side[axis];
            let (lo, hi) = (self.inv_lo[axis], self.inv_hi[axis]);
            let x = planes[side][axis] - self.near_origin[axis];
            let y = planes[1 - side][axis] - self.far_origin[axis];
            near = (x * lo).min(x * hi).max(near);
            far = (y * lo).max(y * hi).min(far);
        }
        let near = near * if near > 0.0 { 1.0 - SLACK } else { 1.0 + SLACK };
        let far = far * if far > 0.0 { 1.0 + SLACK } else { 1.0 - SLACK };
        near.max(self.tmin) <= far.min(tmax)
    }
}

/// The largest `tmax` (as the box tests use it) of the rays in the mask `rays`.
fn farthest_tmax(prepared: &[PreparedRay; PACKET_SIZE], rays: u32) -> f32 {
    Lanes(rays)
        .map(|i| prepared[i].box_tmax())
        .fold(f32::NEG_INFINITY, f32::max)
}

impl<const W: usize> WideLayout<W> {
    /// The packet traversal.
    ///
    /// Each stack entry carries the set of rays that reach it (`active`, one bit per ray). At an
    /// inner node every active ray tests the `W` child boxes with the single-ray SIMD kernel, and
    /// each child inherits the rays that hit its box; children are visited nearest first by
    /// their smallest entry distance. At a leaf, each of its rays tests the triangles alone. So
    /// every ray tests exactly the boxes and leaves it would reach alone (in the packet's order
    /// rather than its own), and the traversal's bookkeeping — stack, ordering, node fetch — is
    /// paid once per packet. A postponed child is dropped when it lies beyond the closest hit of
    /// every ray that reaches it.
    ///
    /// Before any of that, [`PacketBounds`] tests the root box against the whole packet at once.
    #[inline(always)]
    fn closest_hit_packet_with<C: Counter, K: BoxKernel<W>>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
        counter: &mut C,
    ) {
        debug_assert!(rays.len() <= PACKET_SIZE && rays.len() == hits.len());
        hits.fill(None);
        let Some((root, root_bounds, _)) = self.root else {
            return;
        };
        let unused = PreparedRay::new(&Ray::new(glam::Vec3::ZERO, glam::Vec3::X));
        let mut prepared = [unused; PACKET_SIZE];
        let mut valid = 0u32;
        for (i, ray) in rays.iter().enumerate() {
            if ray.is_valid() {
                prepared[i] = PreparedRay::new(ray);
                prepared[i].bound_errors_within(&root_bounds);
                valid |= 1 << i;
            }
        }
        let diagonal = root_bounds.extent().length();
        if let Some(bounds) = PacketBounds::new(&prepared, valid, diagonal) {
            let tmax = farthest_tmax(&prepared, valid);
            counter.boxes_tested(1);
            if !bounds.hits(&root_bounds, tmax) {
                return;
            }
        }
        let mut active = 0u32;
        for i in Lanes(valid) {
            counter.boxes_tested(1);
            active |= u32::from(root_bounds.hit_by(&prepared[i])) << i;
        }
        if active == 0 {
            return;
        }
        let box_rays = prepared.map(|r| BoxRay::new(&r));
        let mut stack: TraversalStack<(u32, u32, f32), 64> = TraversalStack::new();
        let mut current = root;
        loop {
            counter.node_visited();
            if current & LEAF != 0 {
                let first = (current & LEAF_FIRST_MASK) as usize;
                let count = ((current & !LEAF) >> LEAF_COUNT_SHIFT) as usize + 1;
                for i in Lanes(active) {
                    let ray = &mut prepared[i];
                    for packet in &self.packets[first..first + count] {
                        counter.triangles_tested(4);
                        let test = packet.test(ray);
                        for lane in Lanes(test.hit) {
                            record_hit(test.hit(lane), packet.ids[lane], ray, &mut hits[i]);
                        }
                        for lane in Lanes(test.undecided) {
                            let triangle = packet.triangle(lane);
                            record_closer_hit(&triangle, packet.ids[lane], ray, &mut hits[i]);
                        }
                    }
                }
            } else {
                let node = &self.nodes[current as usize];
                let mut reached_by = [0u32; W];
                let mut entry = [f32::INFINITY; W];
                for i in Lanes(active) {
                    counter.boxes_tested(W as u32);
                    let ray = &prepared[i];
                    let (mask, near) =
                        K::test(&node.boxes, &box_rays[i], ray.box_tmin(), ray.box_tmax());
                    for lane in Lanes(mask) {
                        reached_by[lane] |= 1 << i;
                        entry[lane] = entry[lane].min(near[lane]);
                    }
                }
                // Farthest first onto the stack, so that the nearest is visited next.
                let mut order = [(0u32, 0u32, 0.0f32); W];
                let mut n = 0;
                for lane in 0..W {
                    if reached_by[lane] == 0 {
                        continue;
                    }
                    let item = (node.children[lane], reached_by[lane], entry[lane]);
                    let mut k = n;
                    while k > 0 && order[k - 1].2 < item.2 {
                        order[k] = order[k - 1];
                        k -= 1;
                    }
                    order[k] = item;
                    n += 1;
                }
                if n > 0 {
                    for &item in &order[..n - 1] {
                        self.prefetch(item.0);
                        stack.push(item);
                    }
                    (current, active) = (order[n - 1].0, order[n - 1].1);
                    continue;
                }
            }
            (current, active) = loop {
                match stack.pop() {
                    Some((n, rays, near)) if near <= farthest_tmax(&prepared, rays) => {
                        break (n, rays)
                    }
                    Some(_) => continue,
                    None => return,
                }
            };
        }
    }

    /// The packet traversal compiled with AVX. Call only when the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn closest_hit_packet_avx<C: Counter>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
        counter: &mut C,
    ) {
        self.closest_hit_packet_with::<C, AvxBoxes>(rays, hits, counter)
    }

    /// Closest hits of a packet of up to [`PACKET_SIZE`] rays; see the module comment.
    pub(super) fn closest_hit_packet_dispatch<C: Counter>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
        counter: &mut C,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.traverses_with_avx() {
            // SAFETY: `use_avx` is set only when the CPU reported AVX.
            return unsafe { self.closest_hit_packet_avx(rays, hits, counter) };
        }
        self.closest_hit_packet_with::<C, DefaultBoxes>(rays, hits, counter)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, Builder};
    use crate::mesh::procedural::default_scene;
    use crate::{Accelerator, BruteForce};
    use glam::Vec3;

    /// Camera rays over the default scene, in scanline order, spanning `fov` (radians, about)
    /// across; some packets straddle the changes of direction sign.
    fn camera_rays(width: usize, height: usize, fov: f32) -> Vec<Ray> {
        let eye = Vec3::new(6.0, 4.0, 7.0);
        let forward = (Vec3::ZERO - eye).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        let mut rays = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let sx = (x as f32 + 0.5) / width as f32 * 2.0 - 1.0;
                let sy = (y as f32 + 0.5) / height as f32 * 2.0 - 1.0;
                rays.push(Ray::new(eye, forward + fov / 2.0 * (sx * right - sy * up)));
            }
        }
        rays
    }

    #[test]
    fn packets_answer_like_single_rays_and_brute_force() {
        let mesh = default_scene(2);
        let tree = BinnedSahBuilder::default().build(&mesh);
        let mut rays = camera_rays(61, 37, 0.3);
        // Invalid rays and a ray along an axis inside packets.
        rays[3].direction = Vec3::ZERO;
        rays[17].origin.x = f32::NAN;
        rays[40] = Ray::new(Vec3::new(0.0, 0.0, 9.0), -Vec3::Z);
        let brute = BruteForce::new(&mesh);
        let expected: Vec<_> = rays.iter().map(|r| brute.intersect(r)).collect();
        for layout in [
            &WideLayout::<4>::new(&tree, &mesh) as &dyn Accelerator,
            &WideLayout::<8>::new(&tree, &mesh),
        ] {
            assert_eq!(layout.intersect_coherent(&rays), expected);
            let mut stats = crate::TraversalStats::default();
            assert_eq!(
                layout.intersect_coherent_counted(&rays, &mut stats),
                expected
            );
            assert_eq!(stats.rays, rays.len() as u64);
        }
    }

    #[test]
    fn packet_bounds_contain_every_rays_interval() {
        let mesh = default_scene(1);
        let rays = camera_rays(64, 16, 0.5);
        let prepared: Vec<PreparedRay> = rays.iter().map(PreparedRay::new).collect();
        let boxes: Vec<Aabb> = mesh.triangles().map(|t| t.bounds()).collect();
        let mut coherent = 0;
        for chunk in prepared.chunks(PACKET_SIZE) {
            // Packets across a change of direction sign are traced ray by ray.
            let Some(bounds) = PacketBounds::new(chunk, (1 << chunk.len()) - 1, 100.0) else {
                continue;
            };
            coherent += 1;
            for b in &boxes {
                let any = chunk.iter().any(|r| b.hit_by(r));
                let tmax = chunk
                    .iter()
                    .map(|r| r.tmax)
                    .fold(f32::NEG_INFINITY, f32::max);
                assert!(!any || bounds.hits(b, tmax));
            }
        }
        assert!(coherent >= prepared.len() / PACKET_SIZE / 2);
    }
}
