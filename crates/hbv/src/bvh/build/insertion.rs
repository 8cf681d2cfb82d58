//! The seed's construction: incremental insertion (Goldsmith & Salmon 1987, "Automatic creation
//! of object hierarchies for ray tracing", IEEE CG&A 7(5)).

use super::{primitive_bounds, Builder, InsertionOrder};
use crate::bvh::placement::{PlacedItem, PlacementSearch};
use crate::bvh::tree::BuildTree;
use crate::mesh::TriangleMesh;

/// Options of [`InsertionBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InsertionConfig {
    /// Order in which triangles are inserted. Default: shuffled with a fixed seed.
    pub order: InsertionOrder,
    /// Most triangles a leaf may hold. Default 1, the seed's model: every triangle in a leaf of
    /// its own, whose box is tested by its parent.
    pub max_leaf_size: usize,
}

impl Default for InsertionConfig {
    fn default() -> Self {
        Self {
            order: InsertionOrder::default(),
            max_leaf_size: 1,
        }
    }
}

/// Builds a tree by inserting triangles one at a time, each where it increases the tree cost
/// E\[X\] least (see [`crate::bvh::placement`] for the candidates, their costs and the
/// branch-and-bound search). Degenerate triangles are left out: they are never hit.
///
/// Expected time O(n log n): each insertion searches about one root-to-leaf path.
#[derive(Clone, Debug, Default)]
pub struct InsertionBuilder {
    pub config: InsertionConfig,
}

impl Builder for InsertionBuilder {
    fn name(&self) -> &'static str {
        "insertion"
    }

    fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        self.build_with_report(mesh).0
    }
}

impl InsertionBuilder {
    pub fn new(config: InsertionConfig) -> Self {
        Self { config }
    }

    /// [`InsertionBuilder::build`], also returning the mean number of nodes the placement search
    /// evaluated per insertion (the algorithmic work, which grows like log n).
    pub fn build_with_report(&self, mesh: &TriangleMesh) -> (BuildTree, f64) {
        let bounds = primitive_bounds(mesh);
        let mut order: Vec<u32> = (0..bounds.len() as u32)
            .filter(|&p| !bounds[p as usize].is_empty())
            .collect();
        self.config.order.arrange(&mut order, &bounds);

        let inserted = order.len();
        let max_leaf_size = self.config.max_leaf_size.max(1);
        let mut tree = BuildTree::with_capacity(2 * order.len());
        let mut search = PlacementSearch::new();
        for p in order {
            let b = bounds[p as usize];
            let item = PlacedItem {
                bounds: b,
                own_cost: b.surface_area(),
                may_join_leaf: true,
            };
            let (placement, _) = search.find(&tree, &item, max_leaf_size);
            tree.attach_prim(placement, p, b);
        }
        (tree, search.evaluated() as f64 / inserted.max(1) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::cost::expected_tests;
    use crate::bvh::tree::NodeContent;
    use crate::mesh::procedural::{icosphere, torus};
    use glam::Vec3;

    fn orders() -> [InsertionOrder; 3] {
        [
            InsertionOrder::Input,
            InsertionOrder::Shuffle { seed: 7 },
            InsertionOrder::Morton,
        ]
    }

    #[test]
    fn every_order_and_leaf_size_gives_a_valid_tree() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.5, 24, 12);
        let bounds = primitive_bounds(&mesh);
        for order in orders() {
            for max_leaf_size in [1, 2, 4] {
                let tree = InsertionBuilder::new(InsertionConfig {
                    order,
                    max_leaf_size,
                })
                .build(&mesh);
                tree.validate(&bounds, max_leaf_size)
                    .unwrap_or_else(|e| panic!("{order:?} {max_leaf_size}: {e}"));
            }
        }
    }

    #[test]
    fn boxes_are_tight() {
        // Insertion only grows boxes to what they must hold: each box is its children's union.
        let mesh = icosphere(Vec3::ZERO, 1.0, 3);
        let tree = InsertionBuilder::default().build(&mesh);
        let bounds = primitive_bounds(&mesh);
        tree.walk(|id, _| {
            let n = tree.node(id);
            let union = match &n.content {
                NodeContent::Internal(c) => c.iter().fold(crate::geometry::Aabb::EMPTY, |b, &c| {
                    b.union(&tree.node(c).bounds)
                }),
                NodeContent::Leaf(p) => p.iter().fold(crate::geometry::Aabb::EMPTY, |b, &p| {
                    b.union(&bounds[p as usize])
                }),
            };
            assert_eq!(n.bounds, union, "node {id}");
        });
    }

    #[test]
    fn two_far_apart_pairs_are_grouped() {
        // Four unit triangles in two distant pairs: the optimal tree groups each pair.
        let tri = |x: f32| {
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
            ]
        };
        let positions: Vec<Vec3> = [0.0, 0.5, 100.0, 100.5]
            .iter()
            .flat_map(|&x| tri(x))
            .collect();
        let indices = (0..4u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let mesh = TriangleMesh::new(positions, indices).unwrap();
        let tree = InsertionBuilder::new(InsertionConfig {
            order: InsertionOrder::Input,
            max_leaf_size: 1,
        })
        .build(&mesh);
        let root = tree.node(tree.root().unwrap());
        assert_eq!(root.arity(), 2);
        for &c in root.children() {
            let mut prims: Vec<u32> = tree
                .node(c)
                .children()
                .iter()
                .flat_map(|&l| tree.node(l).prims().to_vec())
                .collect();
            prims.sort();
            assert!(prims == vec![0, 1] || prims == vec![2, 3], "{prims:?}");
        }
    }

    #[test]
    fn degenerate_triangles_are_left_out() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0];
        let mesh = TriangleMesh::new(positions, vec![[0, 1, 3], [0, 1, 2], [2, 2, 2]]).unwrap();
        let tree = InsertionBuilder::default().build(&mesh);
        let root = tree.node(tree.root().unwrap());
        assert_eq!(root.prims(), &[1]);
        assert_eq!(expected_tests(&tree), 1.0);
    }

    #[test]
    fn shuffled_tree_is_much_cheaper_than_testing_everything() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 4);
        let tree = InsertionBuilder::default().build(&mesh);
        let e = expected_tests(&tree);
        assert!(e < 0.05 * mesh.triangle_count() as f64, "E[X] = {e}");
    }
}
