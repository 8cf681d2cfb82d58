//! `hbv.BVH(mesh, builder=..., layout=..., optimize=..., leaf_size=..., quality=...)`: the
//! arguments checked against the library's name tables ([`BuilderKind`], [`LayoutKind`],
//! [`BuildQuality`]).

use std::sync::Arc;

use hbv::bvh::build::{BuildQuality, BuilderKind, BuilderOptions};
use hbv::bvh::layout::{AnyLayout, LayoutKind, LayoutOptions, Wide8Layout};
use hbv::bvh::optimize::ReinsertionOptimizer;
use hbv::bvh::BuildTree;
use hbv::{Accelerator, TriangleMesh};
use pyo3::exceptions::PyValueError;
use pyo3::PyResult;

/// The widest leaf the builders make (`LeafPolicy` clamps to 255); the wide layouts split
/// leaves of more than 64 triangles themselves, the other layouts take any size.
pub const MAX_LEAF_SIZE: usize = 255;

/// What a BVH is built from: the constructor's arguments, checked.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// The builder; `None` for a tree loaded from a file whose settings name no builder of
    /// the table (shown as `"saved"`).
    pub builder: Option<BuilderKind>,
    pub layout: LayoutKind,
    pub optimize: bool,
    pub leaf_size: Option<usize>,
}

impl BuildOptions {
    /// The constructor's arguments: the builder, optimizer and leaf size of `quality`, each
    /// replaced by the argument given for it (`None`: not given). Without `optimize`, a mesh of
    /// at most 1,024 `triangles` is optimized at any quality, where it costs about a
    /// millisecond ([`ReinsertionOptimizer::pays_by_default`]).
    pub fn from_arguments(
        quality: &str,
        builder: Option<&str>,
        layout: Option<&str>,
        optimize: Option<bool>,
        leaf_size: Option<usize>,
        triangles: usize,
    ) -> PyResult<Self> {
        let quality: BuildQuality = quality
            .parse()
            .map_err(|e| PyValueError::new_err(format!("quality: {e}")))?;
        let chosen = quality.builder_options();
        let optimize = optimize
            .unwrap_or_else(|| chosen.optimize || ReinsertionOptimizer::pays_by_default(triangles));
        Self::new(
            builder.unwrap_or(quality.builder().name()),
            layout,
            optimize,
            leaf_size.or(chosen.leaf_size),
        )
    }

    /// Checks the names (case ignored, `_` and `-` both accepted) and the leaf size.
    pub fn new(
        builder: &str,
        layout: Option<&str>,
        optimize: bool,
        leaf_size: Option<usize>,
    ) -> PyResult<Self> {
        let builder: BuilderKind = builder
            .parse()
            .map_err(|e| PyValueError::new_err(format!("builder: {e}")))?;
        let layout: LayoutKind = layout
            .unwrap_or(LayoutKind::Wide8.name())
            .parse()
            .map_err(|e| PyValueError::new_err(format!("layout: {e}")))?;
        if let Some(k) = leaf_size {
            if !(1..=MAX_LEAF_SIZE).contains(&k) {
                return Err(PyValueError::new_err(format!(
                    "leaf_size: expected 1 to {MAX_LEAF_SIZE}, got {k}"
                )));
            }
        }
        Ok(Self {
            builder: Some(builder),
            layout,
            optimize,
            leaf_size,
        })
    }

    /// The builder's name, or `"saved"` for a tree whose file names none of the table.
    pub fn builder_name(&self) -> &'static str {
        self.builder.map_or("saved", BuilderKind::name)
    }

    /// The builder and its options (a loaded tree's options, with no builder, name the default
    /// builder).
    fn builder_and_options(&self) -> (BuilderKind, BuilderOptions) {
        let options = BuilderOptions {
            leaf_size: self.leaf_size,
            optimize: self.optimize,
            ..BuilderOptions::default()
        };
        (self.builder.unwrap_or(BuilderKind::BinnedSah), options)
    }

    /// Builds the tree, optimized by reinsertion (Bittner et al. 2013) when asked.
    pub fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        let (builder, options) = self.builder_and_options();
        builder.build(mesh, &options)
    }

    /// What a new BVH builds first: the layout straight from `mesh`, with no build tree, where
    /// the library can ([`LayoutKind::builds_direct`]: binned SAH without optimization into wide
    /// nodes of meshes large enough that it is sooner; the same answers as the layout of
    /// [`BuildOptions::build`]'s tree, whose nodes differ only in leaves of four triangles or
    /// fewer); the tree otherwise.
    pub fn build_first(&self, mesh: &TriangleMesh) -> FirstBuild {
        let (builder, options) = self.builder_and_options();
        if !self.layout.builds_direct(mesh, builder, &options) {
            return FirstBuild::Tree(builder.build(mesh, &options));
        }
        let layout_options = LayoutOptions::default();
        match self
            .layout
            .build_and_lay_out(mesh, builder, &options, &layout_options)
        {
            AnyLayout::Wide8(wide) => FirstBuild::Wide8(wide),
            other => FirstBuild::Layout(Arc::new(other)),
        }
    }

    /// The layout named, over the tree `tree` gives (asked for only by the layouts made from
    /// it); the wide-8 one is `wide()`'s, which the all-hits queries share.
    pub fn lay_out<'t>(
        &self,
        tree: impl FnOnce() -> &'t BuildTree,
        mesh: &TriangleMesh,
        wide: impl FnOnce() -> Arc<Wide8Layout>,
    ) -> Arc<dyn Accelerator> {
        match self.layout {
            LayoutKind::Wide8 => wide(),
            other => Arc::new(other.lay_out(tree(), mesh, &LayoutOptions::default())),
        }
    }
}

/// What [`BuildOptions::build_first`] built.
pub enum FirstBuild {
    /// The build tree, to lay out on first use.
    Tree(BuildTree),
    /// The wide-8 layout, built straight from the mesh.
    Wide8(Wide8Layout),
    /// Another layout (wide-4), built straight from the mesh.
    Layout(Arc<dyn Accelerator>),
}
