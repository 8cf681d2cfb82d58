//! Packets of eight coherent rays traced through the 8-wide layout together, one ray per AVX
//! lane (Wald, Slusallek, Benthin & Wagner 2001, "Interactive rendering with coherent ray
//! tracing", for packets; Benthin, Wald, Woop, Ernst & Mark 2012, "Combining single and packet
//! ray tracing for arbitrary ray distributions", for leaving a packet once few of its rays are
//! left).
//!
//! Camera rays in pixel order, a lidar's scan lines and sunlight are bundles of nearly parallel
//! rays: neighbours visit almost the same nodes and triangles. Eight of them that share their
//! direction signs and dominant axis (and so the near planes of every box and the axes of the
//! watertight test's shear), and whose beam is narrow against the leaves' size
//! ([`BeamLimit`](beam::BeamLimit)), walk the tree once:
//!
//! - at a node, each child's box is tested against the eight rays at once: the single-ray slab
//!   test ([`box_scalar`](super::box_kernels::box_scalar)) lane by lane, with the box's planes
//!   broadcast and each ray's origin, reciprocal and margins in its lane;
//! - a child is visited by the rays that meet it (its lane mask), nearest first by the least
//!   entry distance among them; a postponed child keeps its eight entry distances, and on pop
//!   each ray drops out whose interval (shrunk to its closest hit so far) ends before its entry,
//!   as the single ray does;
//! - at a leaf, each triangle is tested against the rays of the mask at once: the packet test of
//!   [`TrianglePacket::test`](super::TrianglePacket::test) transposed (one triangle, eight
//!   rays), the same IEEE operations in the same order lane by lane, with the lanes it cannot
//!   decide left to the scalar test;
//! - once fewer than [`SINGLE_BELOW`](traversal::SINGLE_BELOW) rays reach a node, each goes on
//!   alone through that subtree ([`Traversal`](super::traversal::Traversal)), where a packet
//!   would test eight lanes for one or two.
//!
//! Every ray tests the boxes it would test alone (those its own conservative test meets, less
//! those beyond its own closest hit) and every triangle of the leaves it reaches with the
//! single-ray test's bits; its closest hit is the least `(t, prim)` of those hits, whatever the
//! order, and it is blocked if any of them is a hit. So each ray's answer is exactly its
//! single-ray answer (tested below; for any hit, the blocking triangle may be another), and only
//! the work is shared.
//!
//! | file | what it holds |
//! | --- | --- |
//! | `beam.rs` | whether eight rays form a narrow beam, traced as one packet |
//! | `packet_rays.rs` | the eight rays' constants, one AVX lane each |
//! | `box_test.rs` | a node's eight boxes against the packet's rays |
//! | `triangle_test.rs` | one triangle against the packet's rays |
//! | `query.rs` | what a packet's traversal asks of its query |
//! | `closest_hits.rs`, `occluders.rs` | the two queries: closest hits, blocking triangles |
//! | `traversal.rs` | the packet's walk through the tree, and its rays going on alone |
//! | `avx_lanes.rs` | single lanes of AVX registers |

mod avx_lanes;
mod beam;
mod box_test;
mod closest_hits;
mod occluders;
mod packet_rays;
mod query;
mod traversal;
mod triangle_test;

use super::kernels::AvxBoxes;
use super::stream;
use super::WideLayout;
use crate::geometry::Ray;
use crate::query::Hit;
use closest_hits::ClosestHits;
use occluders::Occluders;

/// Rays in a packet: one AVX register of f32.
pub(super) const PACKET_RAYS: usize = 8;

/// The batches with packets of coherent rays: each run of eight consecutive rays goes through
/// `WideLayout::packet_block`, which traces it as a packet if it forms a narrow beam and hands
/// the other rays on to the single-ray batch (`WideLayout::trace_batch`).
impl WideLayout<8> {
    /// The closest-hit batch with packets of coherent rays, compiled with AVX2. Call only when
    /// the CPU has AVX and AVX2
    /// ([`Kernels::AvxRayPackets`](super::kernels::Kernels::AvxRayPackets)).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn closest_hits_avx2(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let Some(limit) = self.beam_limit() else {
            return hits.fill(None);
        };
        // SAFETY (the closure): compiled with AVX2, as this function is.
        let block = |eight: &[Ray; 8], out: &mut [Option<Hit>]| unsafe {
            self.packet_block::<ClosestHits>(eight, out, &limit)
        };
        self.trace_batch::<AvxBoxes, _, true>(rays, hits, stream::closest_leaf_visit!(), block)
    }

    /// The any-hit batch with packets of coherent rays, as
    /// [`WideLayout::closest_hits_avx2`]; single rays take children nearest first or in lane
    /// order, packets nearest first.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn any_hits_avx2<const NEAREST_FIRST: bool>(
        &self,
        rays: &[Ray],
        occluders: &mut [Option<u32>],
    ) {
        let Some(limit) = self.beam_limit() else {
            return occluders.fill(None);
        };
        // SAFETY (the closure): compiled with AVX2, as this function is.
        let block = |eight: &[Ray; 8], out: &mut [Option<u32>]| unsafe {
            self.packet_block::<Occluders>(eight, out, &limit)
        };
        self.trace_batch::<AvxBoxes, _, NEAREST_FIRST>(
            rays,
            occluders,
            stream::any_leaf_visit!(),
            block,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::beam::{is_coherent, BeamLimit};
    use super::*;
    use crate::bvh::build::{BinnedSahBuilder, Builder, InsertionBuilder};
    use crate::bvh::layout::wide::root_filter::RayColumns;
    use crate::mesh::procedural::{default_scene, icosphere, torus};
    use crate::mesh::TriangleMesh;
    use crate::query::TraversalKernel;
    use crate::stats::NoCount;
    use glam::Vec3;
    use proptest::prelude::*;

    fn avx2() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    /// Every run of eight consecutive rays, and the whole batch, answers exactly as each ray
    /// alone: closest hits, and whether each is blocked. Returns how many runs were packets.
    fn check_packets(layout: &WideLayout<8>, rays: &[Ray]) -> Result<usize, TestCaseError> {
        prop_assert!(layout.traces_ray_packets());
        let limit = layout
            .root
            .map(|(_, b, _)| BeamLimit::new(&b, layout.packet_extent));
        let closest: Vec<Option<Hit>> = rays
            .iter()
            .map(|r| {
                r.is_valid()
                    .then(|| layout.closest_hit(r, &mut NoCount))
                    .flatten()
            })
            .collect();
        let blocked: Vec<bool> = rays
            .iter()
            .map(|r| r.is_valid() && layout.any_hit(r, &mut NoCount))
            .collect();
        let mut packets = 0;
        for (k, eight) in rays.chunks_exact(PACKET_RAYS).enumerate() {
            let span = k * PACKET_RAYS..(k + 1) * PACKET_RAYS;
            let columns_of = |eight: &[Ray]| {
                // SAFETY: the caller checked AVX2.
                unsafe { RayColumns::of(eight.try_into().unwrap()) }
            };
            if limit
                .as_ref()
                // SAFETY: as above.
                .is_some_and(|limit| unsafe { is_coherent(&columns_of(eight), limit).is_some() })
            {
                packets += 1;
            }
            let mut hits = [None; PACKET_RAYS];
            layout.closest_hits(eight, &mut hits);
            prop_assert_eq!(&hits[..], &closest[span.clone()], "{:?}", eight);
            let mut occluders = [None; PACKET_RAYS];
            layout.occluders(eight, &mut occluders);
            let found: Vec<bool> = occluders.iter().map(Option::is_some).collect();
            prop_assert_eq!(&found[..], &blocked[span], "{:?}", eight);
        }
        // The whole batch, interleaved and ray by ray (as large and small layouts trace it).
        for interleave in [false, true] {
            let mut layout = layout.clone();
            layout.interleave = interleave;
            let mut hits = vec![None; rays.len()];
            let mut occluders = vec![None; rays.len()];
            layout.closest_hits(rays, &mut hits);
            layout.occluders(rays, &mut occluders);
            prop_assert_eq!(&hits, &closest, "interleaved: {}", interleave);
            let found: Vec<bool> = occluders.iter().map(Option::is_some).collect();
            prop_assert_eq!(&found, &blocked, "interleaved: {}", interleave);
        }
        Ok(packets)
    }

    fn layouts() -> Vec<(TriangleMesh, WideLayout<8>)> {
        let meshes = [
            torus(Vec3::new(0.1, -0.2, 0.3), 1.5, 0.5, 24, 12),
            icosphere(Vec3::new(-0.3, 0.2, 0.1), 1.2, 2),
            default_scene(1),
        ];
        meshes
            .into_iter()
            .map(|m| {
                let tree = BinnedSahBuilder::default().build(&m);
                let layout = WideLayout::<8>::new(&tree, &m);
                (m, layout)
            })
            .collect()
    }

    fn v((x, y, z): (f32, f32, f32)) -> Vec3 {
        Vec3::new(x, y, z)
    }

    fn unit() -> impl Strategy<Value = (f32, f32, f32)> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
    }

    /// How the eight rays of a bundle differ: not at all, by rounding, by a little, by a lot.
    fn spread() -> impl Strategy<Value = f32> {
        prop_oneof![Just(0.0f32), Just(1e-6), Just(1e-3), Just(3e-2)]
    }

    proptest! {
        #![proptest_config(crate::proptest_cases::cases(300))]

        /// Bundles from one place towards near one point of the mesh's box or one of its
        /// vertices (where the lanes' exact tests decide), with random intervals.
        #[test]
        fn converging_bundles_answer_as_single_rays(
            mesh in 0usize..3,
            from in unit(),
            to in unit(),
            vertex in prop::option::of(0usize..10_000),
            spread in spread(),
            jitter in prop::collection::vec((unit(), unit()), PACKET_RAYS),
            interval in prop_oneof![
                Just((0.0f32, f32::INFINITY)),
                (0.0f32..0.5, 0.5f32..1.5),
            ],
        ) {
            prop_assume!(avx2());
            let all = layouts();
            let (mesh, layout) = &all[mesh];
            let b = mesh.bounds();
            let (c, size) = (b.center(), b.extent().max_element());
            let origin = c + v(from).normalize_or(Vec3::X) * 3.0 * size;
            let target = match vertex {
                Some(k) => mesh.positions()[k % mesh.positions().len()],
                None => c + v(to) * 0.5 * size,
            };
            let length = (target - origin).length();
            let rays: Vec<Ray> = jitter
                .iter()
                .map(|&(o, t)| {
                    let (o, t) = (origin + v(o) * spread * size, target + v(t) * spread * size);
                    Ray::new(o, t - o).with_interval(interval.0 * length, interval.1 * length)
                })
                .collect();
            check_packets(layout, &rays)?;
        }

        /// Parallel rays (sunlight) from a row of points, and rays leaving points on the
        /// surface (shadow and bounce rays, `tmin` 0 or a little more): the origins lie on
        /// triangles, where the near-origin rule decides.
        #[test]
        fn parallel_and_leaving_bundles_answer_as_single_rays(
            mesh in 0usize..3,
            direction in unit(),
            start in 0usize..10_000,
            (a, b) in (0.0f32..1.0, 0.0f32..1.0),
            step in prop_oneof![Just(0.0f32), Just(1e-4), Just(1e-2)],
            on_surface in any::<bool>(),
            tmin in prop_oneof![Just(0.0f32), Just(1e-5)],
        ) {
            prop_assume!(avx2());
            let all = layouts();
            let (mesh, layout) = &all[mesh];
            let d = v(direction);
            prop_assume!(d.abs().max_element() > 1e-3);
            let size = mesh.bounds().extent().max_element();
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            let rays: Vec<Ray> = (0..PACKET_RAYS)
                .map(|i| {
                    let origin = if on_surface {
                        // Points on neighbouring triangles.
                        let t = mesh.triangle((start + i) % mesh.triangle_count());
                        t.p0 + a * (t.p1 - t.p0) + b * (t.p2 - t.p0)
                    } else {
                        mesh.bounds().center() - 2.0 * size * d.normalize()
                            + Vec3::new(0.0, 1.0, 0.5) * step * size * i as f32
                    };
                    Ray::new(origin, d).with_interval(tmin, f32::INFINITY)
                })
                .collect();
            check_packets(layout, &rays)?;
        }
    }

    /// Camera rays in pixel order over a torus, from outside and from inside its box: most
    /// packets are coherent, and every one answers as its rays alone.
    #[test]
    fn camera_packets_answer_as_single_rays() {
        if !avx2() {
            return;
        }
        let mesh = torus(Vec3::new(0.1, -0.2, 0.3), 1.5, 0.5, 24, 12);
        for tree in [
            BinnedSahBuilder::default().build(&mesh),
            InsertionBuilder::default().build(&mesh),
        ] {
            let layout = WideLayout::<8>::new(&tree, &mesh);
            for eye in [Vec3::new(4.0, 3.0, 5.0), Vec3::new(0.1, -0.2, 0.3)] {
                let forward = (Vec3::new(0.1, -0.2, 0.3) - eye).normalize_or(Vec3::Z);
                let right = forward.cross(Vec3::Y).normalize();
                let up = right.cross(forward);
                let mut rays = Vec::new();
                // 8 pixels span about 1.9°, as 8 of a 512-pixel image over 120°.
                for y in 0..96 {
                    for x in 0..128 {
                        let sx = (x as f32 + 0.5) / 128.0 * 2.0 - 1.0;
                        let sy = (y as f32 + 0.5) / 96.0 * 2.0 - 1.0;
                        rays.push(Ray::new(eye, forward + 0.6 * (sx * right - sy * up)));
                    }
                }
                let packets = check_packets(&layout, &rays).unwrap();
                assert!(packets > rays.len() / PACKET_RAYS / 3, "{packets} packets");
            }
        }
    }

    /// Packets among invalid rays and rays that miss the tree: a run with an invalid ray is
    /// traced ray by ray, a run that misses is answered at once.
    #[test]
    fn runs_with_invalid_or_missing_rays_answer_as_single_rays() {
        if !avx2() {
            return;
        }
        let (_, layout) = layouts().swap_remove(0);
        let eye = Vec3::new(4.0, 3.0, 5.0);
        let mut rays: Vec<Ray> = (0..64)
            .map(|i| {
                Ray::new(
                    eye,
                    Vec3::new(0.1, -0.2, 0.3) - eye + Vec3::X * 1e-3 * i as f32,
                )
            })
            .collect();
        rays[3].direction = Vec3::ZERO;
        rays[12].origin.x = f32::NAN;
        rays[21].tmin = f32::NAN;
        rays[30].direction = Vec3::new(1e-39, 0.0, 0.0);
        for r in &mut rays[40..48] {
            r.direction = -r.direction;
        }
        let packets = check_packets(&layout, &rays).unwrap();
        assert!(packets >= 3, "{packets} packets");
    }
}
