//! `hbv.BVH(mesh, builder=..., layout=..., optimize=..., leaf_size=...)`: the names of the
//! command line's builders and layouts, turned into the library's.

use std::sync::Arc;

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, InsertionBuilder, InsertionConfig, LbvhBuilder,
    LbvhConfig, MedianBuilder, MedianConfig, SweepSahBuilder, SweepSahConfig,
};
use hbv::bvh::layout::{OrderedLayout, RecursiveLayout, SkipLayout, Wide4Layout, Wide8Layout};
use hbv::bvh::optimize::ReinsertionOptimizer;
use hbv::bvh::BuildTree;
use hbv::{Accelerator, TriangleMesh};
use pyo3::exceptions::PyValueError;
use pyo3::PyResult;

pub const BUILDERS: [&str; 5] = ["binned-sah", "sweep-sah", "insertion", "median", "lbvh"];
pub const LAYOUTS: [&str; 5] = ["wide8", "wide4", "ordered", "recursive", "skip"];
/// The widest leaf the builders make (`LeafPolicy` clamps to 255); the wide layouts split
/// leaves of more than 64 triangles themselves, the other layouts take any size.
pub const MAX_LEAF_SIZE: usize = 255;

/// What a BVH is built from: the constructor's arguments, checked.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    pub builder: String,
    pub layout: String,
    pub optimize: bool,
    pub leaf_size: Option<usize>,
}

fn canonical(name: &str) -> String {
    name.trim().to_ascii_lowercase().replace('_', "-")
}

impl BuildOptions {
    /// Checks the names (`_` and `-` both accepted) and the leaf size.
    pub fn new(
        builder: &str,
        layout: Option<&str>,
        optimize: bool,
        leaf_size: Option<usize>,
    ) -> PyResult<Self> {
        let builder = canonical(builder);
        if !BUILDERS.contains(&builder.as_str()) {
            return Err(PyValueError::new_err(format!(
                "builder: unknown builder {builder:?}; expected one of {}",
                BUILDERS.join(", ")
            )));
        }
        let layout = canonical(layout.unwrap_or("wide8"));
        if !LAYOUTS.contains(&layout.as_str()) {
            return Err(PyValueError::new_err(format!(
                "layout: unknown layout {layout:?}; expected one of {}",
                LAYOUTS.join(", ")
            )));
        }
        if let Some(k) = leaf_size {
            if !(1..=MAX_LEAF_SIZE).contains(&k) {
                return Err(PyValueError::new_err(format!(
                    "leaf_size: expected 1 to {MAX_LEAF_SIZE}, got {k}"
                )));
            }
        }
        Ok(Self {
            builder,
            layout,
            optimize,
            leaf_size,
        })
    }

    /// The builder named, with the leaf size if one was given (else the builder's default; 1
    /// for insertion, the seed's model).
    fn builder(&self) -> Box<dyn Builder> {
        let leaf = |default: usize| self.leaf_size.unwrap_or(default);
        match self.builder.as_str() {
            "insertion" => Box::new(InsertionBuilder::new(InsertionConfig {
                max_leaf_size: leaf(1),
                ..InsertionConfig::default()
            })),
            "sweep-sah" => {
                let mut config = SweepSahConfig::default();
                config.leaf.max_leaf_size = leaf(config.leaf.max_leaf_size);
                Box::new(SweepSahBuilder::new(config))
            }
            "median" => Box::new(MedianBuilder::new(MedianConfig {
                max_leaf_size: leaf(MedianConfig::default().max_leaf_size),
            })),
            "lbvh" => Box::new(LbvhBuilder::new(LbvhConfig {
                max_leaf_size: leaf(LbvhConfig::default().max_leaf_size),
            })),
            _ => {
                let mut config = BinnedSahConfig::default();
                config.leaf.max_leaf_size = leaf(config.leaf.max_leaf_size);
                Box::new(BinnedSahBuilder::new(config))
            }
        }
    }

    /// Builds the tree, optimized by reinsertion (Bittner et al. 2013) when asked.
    pub fn build(&self, mesh: &TriangleMesh) -> BuildTree {
        let mut tree = self.builder().build(mesh);
        if self.optimize {
            ReinsertionOptimizer::default().optimize(&mut tree);
        }
        tree
    }

    /// The layout named, over `tree`; the wide-8 one is `wide()`'s, which the all-hits
    /// queries share.
    pub fn lay_out(
        &self,
        tree: &BuildTree,
        mesh: &TriangleMesh,
        wide: impl FnOnce() -> Arc<Wide8Layout>,
    ) -> Arc<dyn Accelerator> {
        match self.layout.as_str() {
            "wide4" => Arc::new(Wide4Layout::new(tree, mesh)),
            "ordered" => Arc::new(OrderedLayout::new(tree, mesh)),
            "recursive" => Arc::new(RecursiveLayout::new(tree, mesh)),
            "skip" => Arc::new(SkipLayout::new(tree, mesh)),
            _ => wide(),
        }
    }
}
