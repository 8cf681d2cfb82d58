//! The mesh to load and the tree to build over it: options shared by `info` and `trace`.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, ValueEnum};
use hbv::bvh::build::{InsertionBuilder, InsertionConfig, InsertionOrder};
use hbv::bvh::layout::{OrderedLayout, RecursiveLayout, SkipLayout, Wide4Layout, Wide8Layout};
use hbv::bvh::BuildTree;
use hbv::mesh::procedural::default_scene;
use hbv::{Accelerator, TriangleMesh};

/// Detail of the built-in scene (132,480 triangles).
pub const DEFAULT_SCENE_DETAIL: u32 = 4;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BuilderName {
    /// Goldsmith–Salmon incremental insertion (the seed's construction).
    Insertion,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LayoutName {
    /// The n-ary tree as built, depth-first traversal.
    Recursive,
    /// Depth-first array with skip pointers, stackless (the seed's).
    Skip,
    /// Binary tree, nearer child first.
    Ordered,
    /// 4-wide nodes, SIMD box and triangle tests.
    Wide4,
    /// 8-wide nodes, SIMD box and triangle tests.
    Wide8,
}

impl LayoutName {
    /// Lays `tree` out for tracing.
    pub fn lay_out(self, tree: &BuildTree, mesh: &TriangleMesh) -> Box<dyn Accelerator> {
        match self {
            LayoutName::Recursive => Box::new(RecursiveLayout::new(tree, mesh)),
            LayoutName::Skip => Box::new(SkipLayout::new(tree, mesh)),
            LayoutName::Ordered => Box::new(OrderedLayout::new(tree, mesh)),
            LayoutName::Wide4 => Box::new(Wide4Layout::new(tree, mesh)),
            LayoutName::Wide8 => Box::new(Wide8Layout::new(tree, mesh)),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OrderName {
    /// Seeded random permutation (see --seed).
    Shuffle,
    /// The file's face order.
    Input,
    /// Morton order of the triangles' box centres.
    Morton,
}

#[derive(Args, Clone, Debug)]
pub struct BuildArgs {
    /// Tree construction algorithm.
    #[arg(long, value_enum, default_value_t = BuilderName::Insertion)]
    pub builder: BuilderName,
    /// Insertion order of the insertion builder.
    #[arg(long, value_enum, default_value_t = OrderName::Shuffle)]
    pub order: OrderName,
    /// Seed of the shuffled insertion order.
    #[arg(long, default_value_t = 0x5eed)]
    pub seed: u64,
    /// Most triangles per leaf.
    #[arg(long = "leaf-size", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=255))]
    pub leaf_size: u32,
}

impl BuildArgs {
    pub fn insertion_config(&self) -> InsertionConfig {
        InsertionConfig {
            order: match self.order {
                OrderName::Shuffle => InsertionOrder::Shuffle { seed: self.seed },
                OrderName::Input => InsertionOrder::Input,
                OrderName::Morton => InsertionOrder::Morton,
            },
            max_leaf_size: self.leaf_size as usize,
        }
    }

    /// Builds the tree and returns it with the build time in seconds.
    pub fn build(&self, mesh: &TriangleMesh) -> (BuildTree, f64) {
        let (tree, seconds, _) = self.build_with_report(mesh);
        (tree, seconds)
    }

    /// [`BuildArgs::build`], also returning the insertion search's mean nodes evaluated per
    /// triangle.
    pub fn build_with_report(&self, mesh: &TriangleMesh) -> (BuildTree, f64, f64) {
        let start = Instant::now();
        let (tree, evaluated) = match self.builder {
            BuilderName::Insertion => {
                InsertionBuilder::new(self.insertion_config()).build_with_report(mesh)
            }
        };
        (tree, start.elapsed().as_secs_f64(), evaluated)
    }

    /// A one-line description of the builder and its options.
    pub fn describe(&self) -> String {
        let order = match self.order {
            OrderName::Shuffle => format!("shuffle, seed {}", self.seed),
            OrderName::Input => "input".into(),
            OrderName::Morton => "morton".into(),
        };
        format!("insertion (order {order}, leaf size {})", self.leaf_size)
    }
}

/// Loads `path`, or makes the built-in scene when there is none, with the load time in seconds.
pub fn load_mesh(path: Option<&Path>) -> anyhow::Result<(TriangleMesh, String, f64)> {
    let start = Instant::now();
    let (mesh, name) = match path {
        Some(p) => (
            TriangleMesh::load(p).with_context(|| "cannot load mesh".to_string())?,
            p.display().to_string(),
        ),
        None => (
            default_scene(DEFAULT_SCENE_DETAIL),
            format!("built-in scene (detail {DEFAULT_SCENE_DETAIL})"),
        ),
    };
    Ok((mesh, name, start.elapsed().as_secs_f64()))
}

/// `--threads N` as a rayon pool: 0 means all cores.
pub fn thread_pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the thread pool")
}
