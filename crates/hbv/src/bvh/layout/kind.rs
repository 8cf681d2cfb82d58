//! The layouts by name: the one table from a name (`wide8`) to a layout of a tree, used by the
//! command line, the Python module and the examples.

use super::{OrderedLayout, RecursiveLayout, SkipLayout, Wide4Layout, Wide8Layout};
use crate::bvh::build::{BinnedSahConfig, BuilderKind, BuilderOptions};
use crate::bvh::name_table::name_table;
use crate::bvh::BuildTree;
use crate::geometry::Ray;
use crate::mesh::TriangleMesh;
use crate::query::{Hit, TraversalKernel};
use crate::stats::Counter;

/// A layout, by name.
///
/// ```
/// use hbv::bvh::build::{BuilderKind, BuilderOptions};
/// use hbv::bvh::layout::{LayoutKind, LayoutOptions};
/// use hbv::mesh::procedural::icosphere;
/// use hbv::{glam::Vec3, geometry::Ray, Accelerator};
///
/// let mesh = icosphere(Vec3::ZERO, 1.0, 2);
/// let tree = BuilderKind::BinnedSah.build(&mesh, &BuilderOptions::default());
/// let kind: LayoutKind = "wide8".parse().unwrap();
/// let layout = kind.lay_out(&tree, &mesh, &LayoutOptions::default());
/// assert_eq!(layout.kind(), LayoutKind::Wide8);
/// assert!(layout.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LayoutKind {
    /// The n-ary tree as built ([`RecursiveLayout`]).
    Recursive,
    /// Depth-first array with skip pointers, stackless ([`SkipLayout`], the seed's).
    Skip,
    /// Binary, nearer child first ([`OrderedLayout`]).
    Ordered,
    /// 4-wide nodes ([`Wide4Layout`]).
    Wide4,
    /// 8-wide nodes ([`Wide8Layout`]).
    Wide8,
}

/// What a layout is asked for beyond its name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayoutOptions {
    /// Whether the wide-8 layout traces coherent runs of rays as packets
    /// ([`Wide8Layout::with_ray_packets`]; the other layouts have none). Default: on.
    pub ray_packets: bool,
}

impl Default for LayoutOptions {
    fn default() -> Self {
        Self { ray_packets: true }
    }
}

impl LayoutKind {
    /// Every layout, in the order tables list them.
    pub const ALL: [LayoutKind; 5] = [
        LayoutKind::Recursive,
        LayoutKind::Skip,
        LayoutKind::Ordered,
        LayoutKind::Wide4,
        LayoutKind::Wide8,
    ];

    /// The name used on the command line, in Python and in tables.
    pub const fn name(self) -> &'static str {
        match self {
            LayoutKind::Recursive => "recursive",
            LayoutKind::Skip => "skip",
            LayoutKind::Ordered => "ordered",
            LayoutKind::Wide4 => "wide4",
            LayoutKind::Wide8 => "wide8",
        }
    }

    /// One line saying what the layout is, for help texts.
    pub const fn summary(self) -> &'static str {
        match self {
            LayoutKind::Recursive => "The n-ary tree as built, depth-first traversal",
            LayoutKind::Skip => "Depth-first array with skip pointers, stackless (the seed's)",
            LayoutKind::Ordered => "Binary tree, nearer child first",
            LayoutKind::Wide4 => "4-wide nodes, SIMD box and triangle tests",
            LayoutKind::Wide8 => "8-wide nodes, SIMD box and triangle tests",
        }
    }

    /// Lays `tree` (built over `mesh`) out in this layout.
    pub fn lay_out(
        self,
        tree: &BuildTree,
        mesh: &TriangleMesh,
        options: &LayoutOptions,
    ) -> AnyLayout {
        match self {
            LayoutKind::Recursive => AnyLayout::Recursive(RecursiveLayout::new(tree, mesh)),
            LayoutKind::Skip => AnyLayout::Skip(SkipLayout::new(tree, mesh)),
            LayoutKind::Ordered => AnyLayout::Ordered(OrderedLayout::new(tree, mesh)),
            LayoutKind::Wide4 => AnyLayout::Wide4(Wide4Layout::new(tree, mesh)),
            LayoutKind::Wide8 => {
                AnyLayout::Wide8(Wide8Layout::new(tree, mesh).with_ray_packets(options.ray_packets))
            }
        }
    }
}

/// The fewest triangles [`LayoutKind::build_and_lay_out`] builds straight into wide nodes:
/// 2 × 4,096, where the direct builder's two top subtrees are big enough to be built as
/// parallel tasks of their own. Below, the binary builder's parallel recursion then the layout
/// is done sooner on two threads: 10,000 rays' first answer from Python on a prefix of the
/// bunny took 0.94× the time through the tree at 8,000 triangles, 1.23–1.34× at 9,000 and
/// 1.2–1.6× from 10,000 to 50,000 (`bench/python_first_answer.py --baseline`, BENCHMARKS.md
/// "First answer").
pub const DIRECT_BUILD_MIN_TRIANGLES: usize = 8192;

impl LayoutKind {
    /// Builds `mesh` by `builder` and lays it out in this layout, for callers that keep no build
    /// tree: binned SAH without optimization into wide nodes, on meshes of
    /// [`DIRECT_BUILD_MIN_TRIANGLES`] or more, is built straight into them
    /// ([`WideLayout::build_direct`](super::WideLayout::build_direct): the same nodes as
    /// [`BuilderKind::build`] then [`LayoutKind::lay_out`], without the binary tree between;
    /// leaves of up to 64 triangles), anything else through the tree.
    pub fn build_and_lay_out(
        self,
        mesh: &TriangleMesh,
        builder: BuilderKind,
        builder_options: &BuilderOptions,
        options: &LayoutOptions,
    ) -> AnyLayout {
        if self.builds_direct(mesh, builder, builder_options) {
            let mut config = BinnedSahConfig::default();
            config.leaf.max_leaf_size = Self::leaf_size(builder, builder_options);
            match self {
                LayoutKind::Wide4 => {
                    return AnyLayout::Wide4(Wide4Layout::build_direct(mesh, &config))
                }
                LayoutKind::Wide8 => {
                    return AnyLayout::Wide8(
                        Wide8Layout::build_direct(mesh, &config)
                            .with_ray_packets(options.ray_packets),
                    )
                }
                _ => {}
            }
        }
        self.lay_out(&builder.build(mesh, builder_options), mesh, options)
    }

    /// Whether [`LayoutKind::build_and_lay_out`] builds this layout straight from `mesh`, with
    /// no build tree: binned SAH without optimization, leaves of at most 64 triangles, into wide
    /// nodes, on a mesh of [`DIRECT_BUILD_MIN_TRIANGLES`] or more. A caller that may need the
    /// tree later (a file, nearest points) builds it then.
    pub fn builds_direct(
        self,
        mesh: &TriangleMesh,
        builder: BuilderKind,
        builder_options: &BuilderOptions,
    ) -> bool {
        mesh.triangle_count() >= DIRECT_BUILD_MIN_TRIANGLES
            && matches!(self, LayoutKind::Wide4 | LayoutKind::Wide8)
            && builder == BuilderKind::BinnedSah
            && !builder_options.optimize
            && Self::leaf_size(builder, builder_options) <= 64
    }

    /// The most triangles per leaf `builder` makes with `builder_options`.
    fn leaf_size(builder: BuilderKind, builder_options: &BuilderOptions) -> usize {
        builder_options
            .leaf_size
            .unwrap_or(builder.default_leaf_size())
    }
}

name_table!(LayoutKind, "layout");

/// A tree laid out in the layout a [`LayoutKind`] names: answers every
/// [`Accelerator`](crate::Accelerator) query as that layout does (each call is passed on whole,
/// batches included).
#[derive(Clone, Debug)]
pub enum AnyLayout {
    Recursive(RecursiveLayout),
    Skip(SkipLayout),
    Ordered(OrderedLayout),
    Wide4(Wide4Layout),
    Wide8(Wide8Layout),
}

/// `$body` with `$layout` bound to the layout inside `$any`, whatever its kind.
macro_rules! with_layout {
    ($any:expr, $layout:ident => $body:expr) => {
        match $any {
            AnyLayout::Recursive($layout) => $body,
            AnyLayout::Skip($layout) => $body,
            AnyLayout::Ordered($layout) => $body,
            AnyLayout::Wide4($layout) => $body,
            AnyLayout::Wide8($layout) => $body,
        }
    };
}

impl AnyLayout {
    /// The name of this layout.
    pub fn kind(&self) -> LayoutKind {
        match self {
            AnyLayout::Recursive(_) => LayoutKind::Recursive,
            AnyLayout::Skip(_) => LayoutKind::Skip,
            AnyLayout::Ordered(_) => LayoutKind::Ordered,
            AnyLayout::Wide4(_) => LayoutKind::Wide4,
            AnyLayout::Wide8(_) => LayoutKind::Wide8,
        }
    }

    /// Bytes held by the layout's nodes and triangles.
    pub fn memory_bytes(&self) -> usize {
        with_layout!(self, layout => layout.memory_bytes())
    }
}

impl TraversalKernel for AnyLayout {
    fn closest_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<Hit> {
        with_layout!(self, layout => layout.closest_hit(ray, counter))
    }

    fn any_hit<C: Counter>(&self, ray: &Ray, counter: &mut C) -> bool {
        with_layout!(self, layout => layout.any_hit(ray, counter))
    }

    fn any_hit_prim<C: Counter>(&self, ray: &Ray, counter: &mut C) -> Option<u32> {
        with_layout!(self, layout => layout.any_hit_prim(ray, counter))
    }

    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        with_layout!(self, layout => layout.closest_hits(rays, hits))
    }

    fn occluders(&self, rays: &[Ray], occluders: &mut [Option<u32>]) {
        with_layout!(self, layout => layout.occluders(rays, occluders))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::glam::Vec3;
    use crate::mesh::procedural::{icosphere, torus};
    use crate::Accelerator;

    #[test]
    fn building_straight_into_a_layout_answers_as_building_a_tree_first() {
        // Just over DIRECT_BUILD_MIN_TRIANGLES (64 × 65 × 2 = 8,320), so that the wide layouts
        // of binned SAH without optimization are built straight.
        let mesh = torus(Vec3::ZERO, 1.0, 0.4, 64, 65);
        assert!(mesh.triangle_count() >= DIRECT_BUILD_MIN_TRIANGLES);
        let rays: Vec<Ray> = (0..400)
            .map(|k| {
                let a = k as f32 * 0.37;
                Ray::new(
                    Vec3::new(3.0 * a.cos(), 0.01 * k as f32 - 2.0, 3.0 * a.sin()),
                    -Vec3::new(a.cos(), 0.3, a.sin()),
                )
            })
            .collect();
        for builder in [BuilderKind::BinnedSah, BuilderKind::Lbvh] {
            for optimize in [false, true] {
                for leaf_size in [None, Some(1), Some(16), Some(100)] {
                    let options = BuilderOptions {
                        leaf_size,
                        optimize,
                        ..Default::default()
                    };
                    for kind in LayoutKind::ALL {
                        let direct = kind.build_and_lay_out(
                            &mesh,
                            builder,
                            &options,
                            &LayoutOptions::default(),
                        );
                        let tree = builder.build(&mesh, &options);
                        let through_tree = kind.lay_out(&tree, &mesh, &LayoutOptions::default());
                        assert_eq!(direct.kind(), kind);
                        assert_eq!(
                            direct.intersect_batch(&rays),
                            through_tree.intersect_batch(&rays),
                            "{builder} {kind} {options:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for kind in LayoutKind::ALL {
            assert_eq!(kind.to_string().parse::<LayoutKind>(), Ok(kind));
        }
        assert_eq!("WIDE8".parse::<LayoutKind>(), Ok(LayoutKind::Wide8));
        let error = "bvh8".parse::<LayoutKind>().unwrap_err();
        assert_eq!(
            error.to_string(),
            "unknown layout \"bvh8\"; expected one of recursive, skip, ordered, wide4, wide8"
        );
    }

    #[test]
    fn every_layout_answers_as_the_layout_it_holds() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 2);
        let tree = BuilderKind::BinnedSah.build(&mesh, &BuilderOptions::default());
        let rays: Vec<Ray> = (0..64)
            .map(|i| {
                let a = i as f32 * 0.37;
                Ray::new(
                    Vec3::new(a.cos() * 3.0, a.sin() * 3.0, 0.1 * a),
                    -Vec3::new(a.cos(), a.sin(), 0.05),
                )
            })
            .collect();
        let wide8 = Wide8Layout::new(&tree, &mesh);
        let expected = wide8.intersect_batch(&rays);
        for kind in LayoutKind::ALL {
            let layout = kind.lay_out(&tree, &mesh, &LayoutOptions::default());
            assert_eq!(layout.kind(), kind);
            assert!(layout.memory_bytes() > 0);
            let hits = layout.intersect_batch(&rays);
            for (got, want) in hits.iter().zip(&expected) {
                assert_eq!(got.map(|h| h.prim), want.map(|h| h.prim), "{kind}");
            }
            assert_eq!(
                layout.occluded_batch(&rays),
                wide8.occluded_batch(&rays),
                "{kind}"
            );
        }
    }
}
