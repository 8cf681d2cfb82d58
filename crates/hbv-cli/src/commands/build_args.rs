//! The mesh to load and the tree to build over it: options shared by `info` and `trace`.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, ValueEnum};
use hbv::bvh::build::{BuildQuality, Builder, BuilderKind, BuilderOptions, InsertionOrder};
use hbv::bvh::file::{is_bvh_file, kind_of_bytes, BvhFileKind};
use hbv::bvh::layout::{AnyLayout, LayoutKind, LayoutOptions};
use hbv::bvh::optimize::ReinsertionOptimizer;
use hbv::bvh::BuildTree;
use hbv::mesh::procedural::default_scene;
use hbv::mesh::MeshFormat;
use hbv::scene::{AnyBvhFile, SceneStructure};
use hbv::TriangleMesh;

use super::name_values::{build_quality, builder_kind};

/// Detail of the built-in scene (132,480 triangles).
pub const DEFAULT_SCENE_DETAIL: u32 = 4;

/// The acceleration structure of `trace` and `bench` (`--accel`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum AccelName {
    /// A bounding volume hierarchy (see --builder and --layout).
    Bvh,
    /// A uniform grid with mailboxes (λ = 2; 3D-DDA traversal).
    Grid,
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
    /// Tree construction algorithm [default: --quality's; without it, insertion for `info`
    /// (the seed's construction), binned-sah for `trace` and `bench` (the fastest tree to
    /// trace)].
    #[arg(long, value_parser = builder_kind())]
    pub builder: Option<BuilderKind>,
    /// Build quality: a builder, optimizer and leaf size chosen together. --builder,
    /// --leaf-size and --optimize given with it replace its choices.
    #[arg(long, value_parser = build_quality())]
    pub quality: Option<BuildQuality>,
    /// Insertion order of the insertion builder.
    #[arg(long, value_enum, default_value_t = OrderName::Shuffle)]
    pub order: OrderName,
    /// Seed of the shuffled insertion order.
    #[arg(long, default_value_t = 0x5eed)]
    pub seed: u64,
    /// Improve the tree by reinsertion (Bittner et al. 2013) after building it.
    #[arg(long)]
    pub optimize: bool,
    /// Most triangles per leaf [default: 1 for insertion (the seed's model), the builder's
    /// own default otherwise].
    #[arg(long = "leaf-size", value_parser = clap::value_parser!(u32).range(1..=255))]
    pub leaf_size: Option<u32>,
}

impl Default for BuildArgs {
    /// The command line's defaults: shuffled insertion, leaf size 1, no optimization.
    fn default() -> Self {
        Self {
            builder: None,
            quality: None,
            order: OrderName::Shuffle,
            seed: 0x5eed,
            optimize: false,
            leaf_size: None,
        }
    }
}

impl BuildArgs {
    /// The builder named, or the quality's, or insertion (the seed's) when neither was.
    pub fn builder_name(&self) -> BuilderKind {
        self.builder_or(BuilderKind::Insertion)
    }

    /// The builder named, or the quality's, or `default` when neither was.
    fn builder_or(&self, default: BuilderKind) -> BuilderKind {
        self.builder
            .or(self.quality.map(BuildQuality::builder))
            .unwrap_or(default)
    }

    /// These options, with `builder` used when neither a builder nor a quality was named.
    pub fn or_builder(&self, builder: BuilderKind) -> BuildArgs {
        BuildArgs {
            builder: Some(self.builder_or(builder)),
            ..self.clone()
        }
    }

    /// How a scene built with these options builds and lays out each of its meshes: the
    /// builder named (or `default` when none was), its options, and `layout`.
    pub fn scene_structure(
        &self,
        default: BuilderKind,
        layout: LayoutKind,
        layout_options: LayoutOptions,
    ) -> SceneStructure {
        SceneStructure {
            builder: self.builder_or(default),
            builder_options: self.builder_options(),
            layout,
            layout_options,
        }
    }

    /// The library's options for the builder these flags name: the quality's, each replaced by
    /// the flag given for it.
    pub fn builder_options(&self) -> BuilderOptions {
        let quality = self
            .quality
            .map_or(BuilderOptions::default(), BuildQuality::builder_options);
        BuilderOptions {
            leaf_size: self.leaf_size.map(|k| k as usize).or(quality.leaf_size),
            insertion_order: match self.order {
                OrderName::Shuffle => InsertionOrder::Shuffle { seed: self.seed },
                OrderName::Input => InsertionOrder::Input,
                OrderName::Morton => InsertionOrder::Morton,
            },
            optimize: self.optimize || quality.optimize,
        }
    }

    /// The builder these options name.
    pub fn builder(&self) -> Box<dyn Builder> {
        self.builder_name().builder(&self.builder_options())
    }

    /// Builds the tree (and optimizes it with `--optimize`); returns it with the seconds spent.
    pub fn build(&self, mesh: &TriangleMesh) -> (BuildTree, f64) {
        let built = self.build_with_report(mesh);
        (built.tree, built.build_seconds + built.optimize_seconds)
    }

    /// [`BuildArgs::build`] with the details of the work done.
    pub fn build_with_report(&self, mesh: &TriangleMesh) -> BuildReport {
        let start = Instant::now();
        let (mut tree, search_nodes_per_insertion) = match self.builder_name() {
            BuilderKind::Insertion => self
                .builder_options()
                .insertion_builder()
                .build_with_report(mesh),
            _ => (self.builder().build(mesh), 0.0),
        };
        let build_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        if self.builder_options().optimize {
            ReinsertionOptimizer::default().optimize(&mut tree);
        }
        BuildReport {
            tree,
            build_seconds,
            optimize_seconds: start.elapsed().as_secs_f64(),
            search_nodes_per_insertion,
        }
    }

    /// A one-line description of the builder and its options.
    pub fn describe(&self) -> String {
        let options = self.builder_options();
        let leaf = options
            .leaf_size
            .map_or("default".to_string(), |k| k.to_string());
        let built = match self.builder_name() {
            BuilderKind::Insertion => {
                let order = match self.order {
                    OrderName::Shuffle => format!("shuffle, seed {}", self.seed),
                    OrderName::Input => "input".into(),
                    OrderName::Morton => "morton".into(),
                };
                format!(
                    "insertion (order {order}, leaf size {})",
                    self.builder_options()
                        .insertion_builder()
                        .config
                        .max_leaf_size
                )
            }
            _ => format!("{} (leaf size {leaf})", self.builder().name()),
        };
        let built = if options.optimize {
            built + " + reinsertion optimization"
        } else {
            built
        };
        match self.quality {
            Some(quality) => format!("{built} (quality {quality})"),
            None => built,
        }
    }
}

/// A built tree and what it cost to make.
pub struct BuildReport {
    pub tree: BuildTree,
    pub build_seconds: f64,
    /// 0 without `--optimize`.
    pub optimize_seconds: f64,
    /// The insertion search's mean nodes evaluated per triangle; 0 for the other builders.
    pub search_nodes_per_insertion: f64,
}

/// Loads `path`, or makes the built-in scene when there is none, with the load time in seconds.
/// A `.hbv` file gives its mesh (its tree is dropped; see [`load_input`]); a glTF file or a
/// `.hbv` scene file its scene flattened into one world-space mesh.
pub fn load_mesh(path: Option<&Path>) -> anyhow::Result<(TriangleMesh, String, f64)> {
    let input = load_input(path)?;
    Ok((input.mesh, input.name, input.load_seconds))
}

/// Where a scene comes from: `trace`, `info` and `bench` take either as a [`hbv::Scene`]; the
/// other commands as its flattened mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneSource {
    /// A glTF file (`.gltf`, `.glb`), whose nodes are instances of its meshes (`docs/RAYS.md`,
    /// "Scenes (glTF)"): each mesh is built as it is loaded.
    Gltf,
    /// A `.hbv` scene file (`hbv build SCENE.glb`, `docs/BVH_FILE.md`): each mesh's tree is
    /// laid out as saved, none built again.
    Saved,
}

impl SceneSource {
    /// The scene `path` is, told by its content for a `.hbv` file (whatever its name) and by
    /// its name for glTF; `None` for a mesh, a `.hbv` mesh file, or a `.hbv` file whose header
    /// cannot be read (loading it as a mesh then says what is wrong).
    pub fn of(path: &Path) -> Option<SceneSource> {
        if is_bvh_file(path) {
            return (hbv_kind(path) == Some(BvhFileKind::Scene)).then_some(SceneSource::Saved);
        }
        (MeshFormat::from_path(path) == Some(MeshFormat::Gltf)).then_some(SceneSource::Gltf)
    }

    /// How each mesh's tree and the top level are made, for reports: `build` and `layout`
    /// for a glTF scene, the file's own for a saved one.
    pub fn describe(self, build: &BuildArgs, layout: LayoutKind) -> String {
        match self {
            SceneSource::Gltf => {
                format!(
                    "each mesh: {}, {layout}; top level: binned SAH",
                    build.describe()
                )
            }
            SceneSource::Saved => "each mesh: its saved tree, laid out as saved; top level: \
                                   binned SAH, built as opened"
                .into(),
        }
    }

    /// Refuses building and layout options given with a saved scene, which would otherwise be
    /// ignored: its trees are saved and their layout recorded in the file. `layout_flags` names
    /// the command's layout flags that were given.
    pub fn check_options(
        self,
        path: &Path,
        build: &BuildArgs,
        layout_flags: &[&str],
    ) -> anyhow::Result<()> {
        if self == SceneSource::Saved {
            refuse_build_options(&path.display().to_string(), build, "scene")?;
            if let Some(flag) = layout_flags.first() {
                anyhow::bail!(
                    "{}: a saved scene is laid out as its file says: {flag} applies only to \
                     meshes and glTF scenes (rebuild it with `hbv build`)",
                    path.display()
                );
            }
        }
        Ok(())
    }
}

/// The kind of the `.hbv` file at `path`, from its 64-byte header alone; `None` when the header
/// cannot be read or is not valid.
fn hbv_kind(path: &Path) -> Option<BvhFileKind> {
    use std::io::Read;
    let mut header = Vec::with_capacity(64);
    std::fs::File::open(path)
        .ok()?
        .take(64)
        .read_to_end(&mut header)
        .ok()?;
    kind_of_bytes(&header).ok()
}

/// Loads the scene at `path` (from `source`) with the seconds that took: a glTF scene read and
/// built as `structure` says (each mesh's BVH and the top level), a saved scene opened as its
/// file says (`structure` unused: see [`SceneSource::check_options`]).
pub fn load_scene_file(
    path: &Path,
    source: SceneSource,
    structure: SceneStructure,
) -> anyhow::Result<(hbv::Scene, f64)> {
    let start = Instant::now();
    let scene = match source {
        SceneSource::Gltf => {
            hbv::Scene::load_with_structure(path, structure).context("cannot load scene")?
        }
        SceneSource::Saved => hbv::Scene::open(path).context("cannot load scene")?,
    };
    Ok((scene, start.elapsed().as_secs_f64()))
}

/// What a command's input gives: a mesh, and the tree saved with it when the input is a `.hbv`
/// file (recognized by its magic number, whatever its name).
pub struct Input {
    pub mesh: TriangleMesh,
    pub saved: Option<SavedTree>,
    pub name: String,
    pub load_seconds: f64,
}

/// A tree loaded from a `.hbv` file, and the settings that built it.
pub struct SavedTree {
    pub tree: BuildTree,
    pub settings: String,
}

/// Loads a mesh or a `.hbv` file at `path`, or makes the built-in scene when there is none.
pub fn load_input(path: Option<&Path>) -> anyhow::Result<Input> {
    let start = Instant::now();
    let (mesh, saved, name) = match path {
        // By its magic number, or its name: a damaged or foreign `.hbv` file is then told apart
        // as "not an hbv BVH file", not an unsupported mesh format.
        Some(p)
            if is_bvh_file(p) || p.extension().is_some_and(|e| e.eq_ignore_ascii_case("hbv")) =>
        {
            match AnyBvhFile::load(p).context("cannot load tree")? {
                AnyBvhFile::Mesh(file) => {
                    let saved = SavedTree {
                        tree: file.tree,
                        settings: file.settings,
                    };
                    (file.mesh, Some(saved), p.display().to_string())
                }
                // A saved scene, to a command that takes a mesh: its world-space triangles,
                // as a glTF scene is flattened.
                AnyBvhFile::Scene(scene) => {
                    let flat = scene
                        .flattened()
                        .with_context(|| format!("{}: cannot flatten the scene", p.display()))?;
                    (flat.mesh, None, p.display().to_string())
                }
            }
        }
        Some(p) => (
            TriangleMesh::load(p).with_context(|| "cannot load mesh".to_string())?,
            None,
            p.display().to_string(),
        ),
        None => (
            default_scene(DEFAULT_SCENE_DETAIL),
            None,
            format!("built-in scene (detail {DEFAULT_SCENE_DETAIL})"),
        ),
    };
    Ok(Input {
        mesh,
        saved,
        name,
        load_seconds: start.elapsed().as_secs_f64(),
    })
}

impl Input {
    /// Refuses building options given with a saved tree, which would otherwise be ignored.
    pub fn check_build_options(&self, build: &BuildArgs) -> anyhow::Result<()> {
        if self.saved.is_some() {
            refuse_build_options(&self.name, build, "tree")?;
        }
        Ok(())
    }

    /// The mesh built straight into `layout` when nothing is saved and `build` asks for what
    /// that build makes ([`LayoutKind::builds_direct`]: the same nodes as the tree laid out,
    /// without the tree); with the seconds it took (build and layout) and a description. `None`
    /// otherwise: [`Input::tree`] then builds the tree.
    pub fn direct_layout(
        &self,
        build: &BuildArgs,
        layout: LayoutKind,
        options: &LayoutOptions,
    ) -> Option<(AnyLayout, f64, String)> {
        let (builder, builder_options) = (build.builder_name(), build.builder_options());
        if self.saved.is_some() || !layout.builds_direct(&self.mesh, builder, &builder_options) {
            return None;
        }
        let start = Instant::now();
        let accel = layout.build_and_lay_out(&self.mesh, builder, &builder_options, options);
        let seconds = start.elapsed().as_secs_f64();
        let described = format!(
            "{}, straight into {} nodes",
            build.describe(),
            layout.name()
        );
        Some((accel, seconds, described))
    }

    /// The saved tree, or one built over the mesh with `build`; with the build report and a
    /// description of how the tree was made.
    pub fn tree(self, build: &BuildArgs) -> (TriangleMesh, BuildReport, String) {
        match self.saved {
            Some(saved) => {
                let report = BuildReport {
                    tree: saved.tree,
                    build_seconds: 0.0,
                    optimize_seconds: 0.0,
                    search_nodes_per_insertion: 0.0,
                };
                (self.mesh, report, format!("saved: {}", saved.settings))
            }
            None => {
                let report = build.build_with_report(&self.mesh);
                (self.mesh, report, build.describe())
            }
        }
    }
}

/// Refuses `--builder`, `--quality`, `--optimize` and `--leaf-size` for the input `name`, which
/// holds a saved `what` (a tree, a scene) built already.
fn refuse_build_options(name: &str, build: &BuildArgs, what: &str) -> anyhow::Result<()> {
    if build.builder.is_some()
        || build.quality.is_some()
        || build.optimize
        || build.leaf_size.is_some()
    {
        anyhow::bail!(
            "{name} holds a saved {what}: --builder, --quality, --optimize and --leaf-size apply \
             only to meshes and glTF scenes, built as they are loaded (rebuild it with `hbv \
             build`)"
        );
    }
    Ok(())
}

/// The most threads `--threads` may ask for: starting tens of thousands took minutes, for no
/// gain on any machine this runs on.
pub const MAX_THREADS: usize = 1024;

/// `--threads N` as a rayon pool: 0 means all cores; more than [`MAX_THREADS`] is an error.
pub fn thread_pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
    if threads > MAX_THREADS {
        anyhow::bail!("--threads {threads}: at most {MAX_THREADS} (0 uses every core)");
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the thread pool")
}
