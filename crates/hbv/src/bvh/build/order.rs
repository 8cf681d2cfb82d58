use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

use crate::bvh::morton::morton_code;
use crate::geometry::Aabb;

/// The order in which an incremental builder inserts triangles.
///
/// Goldsmith & Salmon (1987) found that the input order of a modelled scene (often spatially
/// sorted) builds poor trees and that a random order builds good ones; a Morton order is the
/// extreme of spatial sorting. `hbv build-compare` measures all three.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InsertionOrder {
    /// The mesh's face order.
    Input,
    /// A random permutation from a seeded generator (PCG64-MCG): the same seed, the same tree.
    Shuffle { seed: u64 },
    /// Sorted by the Morton code of the triangles' box centres (ties by face order).
    Morton,
}

impl Default for InsertionOrder {
    fn default() -> Self {
        InsertionOrder::Shuffle { seed: 0x5eed }
    }
}

impl InsertionOrder {
    /// Arranges `prims` (triangle ids) in this order; `bounds[p]` is the box of triangle `p`.
    pub fn arrange(&self, prims: &mut [u32], bounds: &[Aabb]) {
        match *self {
            InsertionOrder::Input => prims.sort_unstable(),
            InsertionOrder::Shuffle { seed } => {
                prims.sort_unstable();
                prims.shuffle(&mut Pcg64Mcg::seed_from_u64(seed));
            }
            InsertionOrder::Morton => {
                let centers = prims.iter().fold(Aabb::EMPTY, |b, &p| {
                    b.union_point(bounds[p as usize].center())
                });
                prims.sort_unstable_by_key(|&p| {
                    (morton_code(bounds[p as usize].center(), &centers), p)
                });
            }
        }
    }
}
