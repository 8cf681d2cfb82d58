//! hbv-render: a Whitted-style ray tracer on hbv's accelerators.
//!
//! The pieces, in the order a frame flows through them:
//! - [`scene`]: the TOML scene format, the built-in Cornell box, and [`Scene`]: each mesh once,
//!   placed by instances (a transform, a material each), traced as hbv's two-level
//!   [`hbv::scene::Scene`] or flattened into one [`hbv::TriangleMesh`].
//! - [`Camera`], [`Light`], [`Material`]: what the scene file describes.
//! - [`SceneTracer`]: the two places where rays meet the structures (the two-level scene, or
//!   accelerators over the flattened scene: one for intersection rays, one for shadow rays),
//!   counting rays (and optionally work and time) by [`RayKind`].
//! - [`QueryCacheConfig`]: which ray kinds go through object caches (a shadow cache per light
//!   and tile, a last-hit cache for primary rays), which never change the image.
//! - [`integrator`]: Whitted's recursion (shadow rays, mirror reflection, Fresnel refraction).
//! - [`render()`]: tiles in parallel into a [`Film`], with a progress bar.
//! - [`image_output`]: PNG (8-bit sRGB) and OpenEXR (float) files, passes and cost heatmaps.
//!
//! ```
//! use std::sync::Arc;
//! use hbv::bvh::build::{BinnedSahBuilder, BinnedSahConfig, Builder};
//! use hbv::bvh::layout::Wide8Layout;
//! use hbv_render::{render, RenderConfig, Scene, SceneTracer};
//!
//! let mut scene = Scene::cornell_box();
//! scene.settings.width = 16;
//! scene.settings.height = 12;
//! // The two-level scene: one BVH per mesh, a top level over the instances.
//! let two_level = SceneTracer::two_level(Arc::new(scene.two_level(Default::default())));
//! let frame = render(&scene, &two_level, &RenderConfig::default());
//! assert_eq!(frame.film.radiance.len(), 16 * 12);
//! // The flattened scene, for any accelerator (the uniform grid too).
//! let mesh = scene.flat_mesh();
//! let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(mesh);
//! let bvh: Arc<dyn hbv::Accelerator> = Arc::new(Wide8Layout::new(&tree, mesh));
//! let flat = render(&scene, &SceneTracer::new(bvh.clone(), bvh), &RenderConfig::default());
//! assert_eq!(flat.film.radiance.len(), 16 * 12);
//! ```

pub mod camera;
pub mod color;
pub mod film;
pub mod heatmap;
pub mod image_output;
pub mod integrator;
pub mod light;
pub mod material;
pub mod optics;
pub mod progress;
pub mod query_caches;
pub mod ray_kind;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod tracer;

pub use camera::Camera;
pub use film::{Film, Pass};
pub use light::Light;
pub use material::Material;
pub use query_caches::QueryCacheConfig;
pub use ray_kind::{RayKind, RayStats};
pub use render::{render, Frame, RenderConfig};
pub use scene::{RenderSettings, Scene, SceneError, SceneInstance, SceneMesh};
pub use tracer::SceneTracer;
