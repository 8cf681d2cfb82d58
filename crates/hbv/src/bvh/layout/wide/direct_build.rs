//! The wide layout built straight from a mesh by binned SAH: the binary splits of
//! [`BinnedSahBuilder`] chosen node by node and collapsed into `W`-wide nodes as they are made,
//! with no build tree in between.

use super::fragment::Fragment;
use super::leaf_packets::push_leaf_packets;
use super::node::{WideNode, MAX_LEAF_TRIANGLES};
use super::WideLayout;
use crate::bvh::build::{
    bounds_and_centroid_bounds, prim_refs, BinCounts, BinnedSahBuilder, BinnedSahConfig, NodeSplit,
    PrimRef, SideBounds,
};
use crate::geometry::Aabb;
use crate::mesh::TriangleMesh;
use rayon::prelude::*;

/// Subtrees of at least this many triangles are built by tasks of their own (`rayon`), each
/// into a [`Fragment`]; smaller ones by the task of the node above them.
const TASK_MIN: usize = 4096;

/// Nodes of at least this many triangles, when a wide node is collapsed from them, open their
/// top levels ahead in parallel ([`DirectBuild::open_ahead`]).
const OPEN_AHEAD_MIN: usize = 1 << 15;

/// A binary node opened ahead: its `(first, len)` and its two children.
type Opened = ((usize, usize), [BinaryNode; 2]);

/// A binary node of the build, not yet laid out: triangles `prims[first..first + len]` of the
/// slice of the wide node being collapsed, their box, the node's depth in the binary tree, and
/// how it is split (`None`: a leaf).
#[derive(Clone, Copy, Debug)]
struct BinaryNode {
    first: usize,
    len: usize,
    bounds: Aabb,
    depth: u32,
    split: Option<NodeSplit>,
}

/// The builder's settings and what every task reads: the mesh, and the binned SAH that picks the
/// splits.
struct DirectBuild<'a> {
    mesh: &'a TriangleMesh,
    sah: BinnedSahBuilder,
}

impl<const W: usize> WideLayout<W> {
    /// Builds the layout over the non-degenerate triangles of `mesh` by binned SAH, without a
    /// build tree: each wide node takes a binary node's split, then splits its child of largest
    /// surface area, and so on, until it has `W` children or only leaves (Wald, Benthin &
    /// Boulos 2008, "Getting rid of packets"; the direct BVH8 build of Embree, Wald et al.
    /// 2014). The splits are those [`BinnedSahBuilder`] with `config` makes, and the nodes those
    /// [`WideLayout::new`] collapses from its tree, except that a node of at most four
    /// triangles is one leaf without being split (the collapse makes it one leaf after).
    ///
    /// Leaves hold 4 to 64 triangles at most (`config.leaf.max_leaf_size` is clamped to
    /// `4..=64`). Subtrees of 4,096 triangles or more are built in parallel (`rayon`) and
    /// joined; large nodes are binned in parallel as by the binary builder. Answers equal
    /// those of any other layout over any tree (the property tests of
    /// `tests/direct_wide_build.rs`).
    pub fn build_direct(mesh: &TriangleMesh, config: &BinnedSahConfig) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_WIDTH;
        let mut config = *config;
        config.leaf.max_leaf_size = config.leaf.max_leaf_size.clamp(4, MAX_LEAF_TRIANGLES);
        config.leaf.min_leaf_size = config.leaf.min_leaf_size.max(4);
        let build = DirectBuild {
            mesh,
            sah: BinnedSahBuilder::new(config),
        };
        let mut prims = prim_refs(mesh);
        if prims.is_empty() {
            return Self::from_parts(Vec::new(), Vec::new(), None);
        }
        let bounds = bounds_and_centroid_bounds(&prims);
        let bins = &mut BinCounts::new_boxed();
        let root = build.plan(&prims, 0, bounds, 0, bins);
        let mut fragment = Fragment::<W>::new();
        let reference = if root.split.is_none() {
            build.push_leaf(&mut fragment, &prims)
        } else {
            fragment = build.build_fragment(&mut prims, root);
            0
        };
        let (nodes, packets) = fragment.join();
        Self::from_parts(nodes, packets, Some((reference, bounds.0)))
    }
}

impl DirectBuild<'_> {
    /// The binary node over `prims`, at `first` in its wide node's slice, with its split chosen.
    fn plan(
        &self,
        prims: &[PrimRef],
        first: usize,
        bounds: SideBounds,
        depth: u32,
        bins: &mut BinCounts,
    ) -> BinaryNode {
        BinaryNode {
            first,
            len: prims.len(),
            bounds: bounds.0,
            depth,
            split: self.sah.choose_split(prims, &bounds, depth, bins),
        }
    }

    /// Splits binary node `node`, whose triangles are `range` (partitioning them), and chooses
    /// its children's splits.
    fn open(
        &self,
        range: &mut [PrimRef],
        node: &BinaryNode,
        bins: &mut BinCounts,
    ) -> [BinaryNode; 2] {
        let split = node.split.expect("only split nodes are opened");
        let (left_len, [left, right]) = split.apply(range);
        let (left_prims, right_prims) = range.split_at(left_len);
        let depth = node.depth + 1;
        [
            self.plan(left_prims, node.first, left, depth, bins),
            self.plan(right_prims, node.first + left_len, right, depth, bins),
        ]
    }

    /// Opens binary node `node` (triangles `range`) and, `levels - 1` levels down, its split
    /// descendants of [`OPEN_AHEAD_MIN`] triangles or more, the two sides of each node in
    /// parallel; appends each opened node's range and children to `opened`. The collapse of a
    /// large node opens these nodes in turn anyway (or, for one it leaves closed, the wide
    /// node made from it does), one after another: opened ahead, the partitions near the root
    /// run on all threads instead of one.
    fn open_ahead(
        &self,
        range: &mut [PrimRef],
        node: &BinaryNode,
        levels: u32,
        bins: &mut BinCounts,
        opened: &mut Vec<Opened>,
    ) {
        let children = self.open(range, node, bins);
        opened.push(((node.first, node.len), children));
        if levels <= 1 {
            return;
        }
        let (left, right) = range.split_at_mut(children[0].len);
        let ahead = |range: &mut [PrimRef], child: &BinaryNode, bins: &mut BinCounts| {
            let mut opened = Vec::new();
            if child.split.is_some() && child.len >= OPEN_AHEAD_MIN {
                self.open_ahead(range, child, levels - 1, bins, &mut opened);
            }
            opened
        };
        let (from_left, from_right) = rayon::join(
            || ahead(left, &children[0], bins),
            || ahead(right, &children[1], &mut BinCounts::new_boxed()),
        );
        opened.extend(from_left);
        opened.extend(from_right);
    }

    /// The children of the wide node made from binary node `node` (over all of `prims`), and
    /// how many: its two children, then the split child of largest surface area opened in turn,
    /// until there are `W` or none is split, as [`WideLayout::new`] collapses a build tree.
    /// Nodes of [`OPEN_AHEAD_MIN`] triangles or more open their top levels ahead, in parallel.
    fn collapse<const W: usize>(
        &self,
        prims: &mut [PrimRef],
        node: &BinaryNode,
        bins: &mut BinCounts,
    ) -> ([BinaryNode; W], usize) {
        let mut ahead = Vec::new();
        if node.len >= OPEN_AHEAD_MIN {
            self.open_ahead(prims, node, W.ilog2(), bins, &mut ahead);
        }
        let mut open = |c: &BinaryNode, bins: &mut BinCounts| {
            let known = ahead.iter().find(|(key, _)| *key == (c.first, c.len));
            match known {
                Some((_, children)) => *children,
                None => self.open(&mut prims[c.first..c.first + c.len], c, bins),
            }
        };
        let mut children = [*node; W];
        let [left, right] = open(node, bins);
        (children[0], children[1]) = (left, right);
        let mut count = 2;
        while count < W {
            let openable = children[..count]
                .iter()
                .enumerate()
                .filter(|(_, c)| c.split.is_some())
                .max_by(|(_, a), (_, b)| {
                    a.bounds.surface_area().total_cmp(&b.bounds.surface_area())
                });
            let Some((k, _)) = openable else {
                break;
            };
            // `swap_remove` of slot `k`, then the opened node's two children at the end.
            let opened = children[k];
            count -= 1;
            children[k] = children[count];
            let [left, right] = open(&opened, bins);
            (children[count], children[count + 1]) = (left, right);
            count += 2;
        }
        (children, count)
    }

    /// Builds the subtree of split binary node `root` over all of `prims` as a fragment (its
    /// wide node at index 0), handing its children of [`TASK_MIN`] triangles or more to tasks
    /// of their own.
    fn build_fragment<const W: usize>(
        &self,
        prims: &mut [PrimRef],
        root: BinaryNode,
    ) -> Fragment<W> {
        let bins = &mut BinCounts::new_boxed();
        let mut fragment = Fragment::new();
        fragment.nodes.push(WideNode::empty());
        if prims.len() < TASK_MIN {
            self.reserve(&mut fragment, prims.len());
            self.fill(&mut fragment, vec![(prims, rebased(root), 0)], bins);
            return fragment;
        }
        let mut work = Vec::new();
        let mut tasks = Vec::new();
        let (children, count) = self.collapse::<W>(prims, &root, bins);
        let mut node = WideNode::empty();
        for (lane, (child, prims)) in carve(prims, &children[..count]).into_iter().enumerate() {
            node.set_box(lane, &child.bounds);
            if child.split.is_none() {
                node.children[lane] = self.push_leaf(&mut fragment, prims);
            } else if child.len >= TASK_MIN {
                tasks.push((lane, prims, child));
            } else {
                node.children[lane] = fragment.nodes.len() as u32;
                work.push((prims, child, fragment.nodes.len() as u32));
                fragment.nodes.push(WideNode::empty());
            }
        }
        fragment.nodes[0] = node;
        let small: usize = work.iter().map(|(p, _, _)| p.len()).sum();
        self.reserve(&mut fragment, small);
        let (parts, ()) = rayon::join(
            || {
                tasks
                    .into_par_iter()
                    .map(|(lane, prims, child)| (lane, self.build_fragment::<W>(prims, child)))
                    .collect::<Vec<_>>()
            },
            || self.fill(&mut fragment, work, bins),
        );
        for (lane, part) in parts {
            fragment.graft(0, lane, part);
        }
        fragment
    }

    /// Room in `fragment` for the nodes and packets of about `triangles` more triangles (3.3
    /// triangles per packet, 4 packets per node in the shared scenes), rather than copies as
    /// the arrays grow.
    fn reserve<const W: usize>(&self, fragment: &mut Fragment<W>, triangles: usize) {
        let packets = triangles / 3 + 1;
        fragment.packets.reserve(packets);
        fragment.nodes.reserve(packets / 3 + 1);
    }

    /// Builds, one task, the subtrees on the `work` list: each a split binary node over its
    /// triangles, to be laid out at a node index reserved in `fragment`. Iterative, so that no
    /// depth overflows the call stack; each wide node's children that are split get consecutive
    /// indices, as [`WideLayout::new`] gives them.
    fn fill<const W: usize>(
        &self,
        fragment: &mut Fragment<W>,
        mut work: Vec<(&mut [PrimRef], BinaryNode, u32)>,
        bins: &mut BinCounts,
    ) {
        while let Some((prims, root, slot)) = work.pop() {
            let (children, count) = self.collapse::<W>(prims, &root, bins);
            let mut node = WideNode::empty();
            for (lane, (child, prims)) in carve(prims, &children[..count]).into_iter().enumerate() {
                node.set_box(lane, &child.bounds);
                node.children[lane] = if child.split.is_none() {
                    self.push_leaf(fragment, prims)
                } else {
                    let index = fragment.nodes.len() as u32;
                    fragment.nodes.push(WideNode::empty());
                    work.push((prims, child, index));
                    index
                };
            }
            fragment.nodes[slot as usize] = node;
        }
    }

    /// Writes the leaf of `prims` into `fragment` and returns its reference.
    fn push_leaf<const W: usize>(&self, fragment: &mut Fragment<W>, prims: &[PrimRef]) -> u32 {
        let mut ids = [0u32; MAX_LEAF_TRIANGLES];
        for (id, p) in ids.iter_mut().zip(prims) {
            *id = p.id;
        }
        push_leaf_packets(&mut fragment.packets, self.mesh, &ids[..prims.len()])
    }
}

/// `node` as the root of its own slice of triangles.
fn rebased(node: BinaryNode) -> BinaryNode {
    BinaryNode { first: 0, ..node }
}

/// `prims` cut into the triangles of each of `children` (whose ranges tile it), each child
/// rebased to its own slice, in the children's order.
fn carve<'p>(
    mut prims: &'p mut [PrimRef],
    children: &[BinaryNode],
) -> Vec<(BinaryNode, &'p mut [PrimRef])> {
    let mut order: Vec<usize> = (0..children.len()).collect();
    order.sort_unstable_by_key(|&k| children[k].first);
    let mut slices: Vec<Option<&'p mut [PrimRef]>> = (0..children.len()).map(|_| None).collect();
    for k in order {
        let (head, tail) = std::mem::take(&mut prims).split_at_mut(children[k].len);
        slices[k] = Some(head);
        prims = tail;
    }
    children
        .iter()
        .zip(slices)
        .map(|(c, s)| (rebased(*c), s.expect("the children tile the node")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::node::{is_leaf, leaf_span};
    use super::*;
    use crate::bvh::build::Builder;
    use crate::mesh::procedural::{default_scene, torus};
    use glam::Vec3;

    /// The sorted face ids of leaf `reference`.
    fn leaf_ids<const W: usize>(layout: &WideLayout<W>, reference: u32) -> Vec<u32> {
        let (first, count) = leaf_span(reference);
        let mut ids: Vec<u32> = layout.packets[first..first + count]
            .iter()
            .flat_map(|p| p.ids)
            .collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// Asserts that two layouts hold the same tree: the same boxes in the same lanes, the same
    /// triangles in each leaf (in any order), node by node from the roots.
    fn assert_same_tree<const W: usize>(a: &WideLayout<W>, b: &WideLayout<W>) {
        let (ra, rb) = (a.root.unwrap(), b.root.unwrap());
        assert_eq!(ra.1, rb.1);
        let mut stack = vec![(ra.0, rb.0)];
        while let Some((x, y)) = stack.pop() {
            assert_eq!(is_leaf(x), is_leaf(y));
            if is_leaf(x) {
                assert_eq!(leaf_ids(a, x), leaf_ids(b, y));
                continue;
            }
            let (nx, ny) = (&a.nodes[x as usize], &b.nodes[y as usize]);
            assert_eq!(nx.boxes, ny.boxes);
            for lane in 0..W {
                if nx.boxes[0][0][lane] <= nx.boxes[1][0][lane] {
                    stack.push((nx.children[lane], ny.children[lane]));
                }
            }
        }
        assert_eq!(a.nodes.len(), b.nodes.len());
        assert_eq!(a.packets.len(), b.packets.len());
    }

    #[test]
    fn the_direct_build_makes_the_tree_the_collapse_makes() {
        let config = BinnedSahConfig::default();
        for mesh in [default_scene(2), torus(Vec3::ZERO, 2.0, 0.6, 300, 100)] {
            let tree = BinnedSahBuilder::new(config).build(&mesh);
            assert_same_tree(
                &WideLayout::<8>::build_direct(&mesh, &config),
                &WideLayout::<8>::new(&tree, &mesh),
            );
            assert_same_tree(
                &WideLayout::<4>::build_direct(&mesh, &config),
                &WideLayout::<4>::new(&tree, &mesh),
            );
        }
    }

    #[test]
    fn one_thread_builds_the_layout_two_threads_build() {
        let mesh = torus(Vec3::ZERO, 2.0, 0.6, 300, 100);
        let config = BinnedSahConfig::default();
        let parallel = WideLayout::<8>::build_direct(&mesh, &config);
        let serial = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| WideLayout::<8>::build_direct(&mesh, &config));
        assert_same_tree(&parallel, &serial);
    }
}
