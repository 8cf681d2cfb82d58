//! `SceneStructure`: which builder and layout a scene gives each of its meshes.

use crate::bvh::build::{BuilderKind, BuilderOptions};
use crate::bvh::layout::{LayoutKind, LayoutOptions};

/// How each mesh of a scene is built and laid out, once, when it is added. Default: binned SAH,
/// wide-8 nodes, every option the builder's and the layout's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneStructure {
    pub builder: BuilderKind,
    pub builder_options: BuilderOptions,
    pub layout: LayoutKind,
    pub layout_options: LayoutOptions,
}

impl Default for SceneStructure {
    fn default() -> Self {
        Self {
            builder: BuilderKind::BinnedSah,
            builder_options: BuilderOptions::default(),
            layout: LayoutKind::Wide8,
            layout_options: LayoutOptions::default(),
        }
    }
}
