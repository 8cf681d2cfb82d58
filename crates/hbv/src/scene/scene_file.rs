//! Scenes in `.hbv` files (format version 2, `docs/BVH_FILE.md`): [`Scene::save`] and
//! [`Scene::open`], their in-memory forms [`Scene::to_hbv_bytes`] and
//! [`Scene::from_hbv_bytes`] (named apart from [`Scene::from_bytes`], which reads glTF), and
//! [`AnyBvhFile`] for a `.hbv` file of either kind.
//!
//! A scene file holds the scene's [`SceneStructure`] (so that the opened scene lays out its
//! meshes, and adds new ones, as the saved one did), each mesh with its tree exactly as a
//! version-1 mesh file holds one and the origin of its stored vertices (a float64 mesh's centre,
//! [`Scene::add_mesh_f64`], so that instances placed or moved later compose it as before), and
//! every instance by id: its mesh, its transform as the scene holds it (the f64 entries,
//! exactly), its mask, and whether it was removed (a hole, so that every id keeps its meaning).
//!
//! **The top level is not stored.** [`Scene::open`] lays out each mesh's saved tree and builds
//! the top level over the live instances ([`Scene::build`]): instances pending at the save
//! (added or moved since the last build or update) are in the opened scene's top level like
//! the others. The opened scene answers every query exactly as the saved one did, ray by ray:
//! the same meshes, trees and transforms give the same world boxes and carried rays, and the
//! answers do not depend on the top level's shape (ties go to the smaller instance, then the
//! smaller `prim`).
//!
//! **Trees.** A scene keeps only each mesh's layout, not the tree it was laid out from, except
//! for a mesh whose vertices moved ([`Scene::set_mesh_positions`] keeps the refitted tree).
//! Saving writes a kept tree as it is, and builds the others again with the scene's builder
//! (builders are deterministic: it is the tree the layout was made from), one mesh at a time,
//! each dropped once written. Opened meshes keep no tree either, as added ones, so saving an
//! opened scene gives the same bytes, except for meshes that had been refitted, whose trees are
//! then built afresh (with the same answers: a layout's answers do not depend on its tree).

use std::borrow::Cow;
use std::io;
use std::path::Path;

use rayon::prelude::*;

use glam::DVec3;

use super::instance::{Instance, InstanceState};
use super::{Scene, SceneStructure};
use crate::atomic_file::Replace;
use crate::bvh::file::{
    kind_of_bytes, parse_scene, read_file, save_counted, write_scene, BvhFile, BvhFileError,
    BvhFileKind, BvhFileProblem, SceneMeshParts, StoredInstance, StoredScene, StoredStructure,
};
use crate::geometry::Aabb;
use crate::scene::InstanceTransform;

impl Scene {
    /// Saves the scene as a `.hbv` scene file at `path`, atomically as [`BvhFile::save`] saves
    /// a mesh: a reader never sees half a file, a failed save leaves `path` as it was, and with
    /// [`Replace::Never`] a file at `path` (even one created during the save) is never replaced.
    /// Returns the number of bytes written. See the module notes for what is stored.
    pub fn save(&self, path: impl AsRef<Path>, replace: Replace) -> io::Result<u64> {
        save_counted(path.as_ref(), replace, |mut out| self.write_hbv(&mut out))
    }

    /// Writes the scene's `.hbv` scene file to `out` ([`Scene::save`] makes it atomic on disk).
    pub fn write_hbv(&self, out: &mut impl io::Write) -> io::Result<()> {
        let s = &self.structure;
        let meshes = self.meshes.iter().map(|m| SceneMeshParts {
            mesh: &m.mesh,
            tree: match &m.tree {
                Some(kept) => Cow::Borrowed(kept),
                None => Cow::Owned(s.builder.build(&m.mesh, &s.builder_options)),
            },
            settings: settings_line(s, m.tree.is_some()),
        });
        let origins: Vec<[f64; 3]> = self.meshes.iter().map(|m| m.origin.to_array()).collect();
        let instances = self.stored_instances();
        write_scene(stored_structure(s), &origins, &instances, meshes, out)
    }

    /// The scene's `.hbv` scene file, in memory (for pickling); read back by
    /// [`Scene::from_hbv_bytes`].
    pub fn to_hbv_bytes(&self) -> Vec<u8> {
        let mut bytes = Vec::new();
        self.write_hbv(&mut bytes).expect("writing to memory");
        bytes
    }

    /// Opens the `.hbv` scene file at `path` ([`Scene::save`]): every part is checked, each
    /// mesh's tree laid out as the file's structure says and the top level built, no mesh built
    /// again. Read whole into memory, as [`BvhFile::load`] reads a mesh file. A mesh file (format
    /// version 1) is refused with [`BvhFileProblem::WrongKind`]; [`AnyBvhFile::load`] reads either.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, BvhFileError> {
        let path = path.as_ref();
        Self::from_hbv_bytes(&read_file(path)?, path)
    }

    /// Reads a `.hbv` scene file's bytes ([`Scene::to_hbv_bytes`]); `source` names them in
    /// errors. Not [`Scene::from_bytes`], which reads glTF.
    pub fn from_hbv_bytes(bytes: &[u8], source: &Path) -> Result<Self, BvhFileError> {
        parse_scene(bytes)
            .and_then(scene_of)
            .map_err(|problem| BvhFileError {
                path: source.into(),
                problem,
            })
    }

    /// Every instance as its file records it, by id: its transform as the scene holds it, which
    /// places the mesh's stored vertices (a float64 mesh's origin composed in).
    fn stored_instances(&self) -> Vec<StoredInstance> {
        self.instances
            .iter()
            .map(|i| {
                let affine = i.transform.affine();
                StoredInstance {
                    mesh: i.mesh,
                    mask: i.mask,
                    removed: i.state == InstanceState::Removed,
                    rows: std::array::from_fn(|r| {
                        let row = affine.matrix3.row(r);
                        [row.x, row.y, row.z, affine.translation[r]]
                    }),
                }
            })
            .collect()
    }
}

/// A `.hbv` file of either kind, as [`AnyBvhFile::load`] finds it.
#[derive(Clone, Debug)]
pub enum AnyBvhFile {
    /// A mesh file (format version 1): one mesh, its tree and its settings line.
    Mesh(BvhFile),
    /// A scene file (format version 2), opened as [`Scene::open`] opens one.
    Scene(Scene),
}

impl AnyBvhFile {
    /// Reads the `.hbv` file at `path`, whichever kind its header says it is, with every check
    /// of [`BvhFile::load`] or [`Scene::open`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self, BvhFileError> {
        let path = path.as_ref();
        Self::from_bytes(&read_file(path)?, path)
    }

    /// Reads a `.hbv` file's bytes of either kind; `source` names them in errors.
    pub fn from_bytes(bytes: &[u8], source: &Path) -> Result<Self, BvhFileError> {
        let kind = kind_of_bytes(bytes).map_err(|problem| BvhFileError {
            path: source.into(),
            problem,
        })?;
        Ok(match kind {
            BvhFileKind::Mesh => AnyBvhFile::Mesh(BvhFile::from_bytes(bytes, source)?),
            BvhFileKind::Scene => AnyBvhFile::Scene(Scene::from_hbv_bytes(bytes, source)?),
        })
    }

    /// Which kind of file it was.
    pub fn kind(&self) -> BvhFileKind {
        match self {
            AnyBvhFile::Mesh(_) => BvhFileKind::Mesh,
            AnyBvhFile::Scene(_) => BvhFileKind::Scene,
        }
    }
}

fn stored_structure(s: &SceneStructure) -> StoredStructure {
    StoredStructure {
        builder: s.builder,
        builder_options: s.builder_options,
        layout: s.layout,
        layout_options: s.layout_options,
    }
}

/// The settings line of each mesh file inside a scene file, in the words `hbv build` uses for
/// a mesh: the builder, its leaf size, its optimization, and whether the tree is a refit.
fn settings_line(s: &SceneStructure, refitted: bool) -> String {
    let leaf = s
        .builder_options
        .leaf_size
        .unwrap_or(s.builder.default_leaf_size());
    let mut line = format!("{} (leaf size {leaf})", s.builder);
    if s.builder_options.optimize {
        line += " + reinsertion optimization";
    }
    if refitted {
        line += ", refitted after its vertices moved";
    }
    line
}

/// The scene a checked file describes: its meshes' trees laid out (in parallel), its instances
/// put back by id as the scene held them (their transforms place the stored vertices, so they
/// are not composed with the meshes' origins again; removed ones are holes), the top level
/// built. Transforms are checked as [`InstanceTransform::new`] checks every transform.
fn scene_of(stored: StoredScene) -> Result<Scene, BvhFileProblem> {
    let s = stored.structure;
    let structure = SceneStructure {
        builder: s.builder,
        builder_options: s.builder_options,
        layout: s.layout,
        layout_options: s.layout_options,
    };
    let mut scene = Scene::with_structure(structure);
    let laid_out: Vec<_> = stored
        .meshes
        .into_par_iter()
        .map(|(file, origin)| {
            let layout =
                structure
                    .layout
                    .lay_out(&file.tree, &file.mesh, &structure.layout_options);
            (file.mesh, layout, DVec3::from_array(origin))
        })
        .collect();
    for (mesh, layout, origin) in laid_out {
        scene.push_mesh(mesh, layout, origin);
    }
    for (id, stored) in stored.instances.iter().enumerate() {
        let transform =
            InstanceTransform::from_rows(stored.rows).map_err(|e| BvhFileProblem::Invalid {
                place: format!("instance {id}"),
                reason: e.to_string(),
            })?;
        // The mesh id was checked against the mesh count by the reader.
        let mesh_box = &scene.meshes[stored.mesh as usize].bounds;
        let instance = Instance::new(stored.mesh, transform, stored.mask, mesh_box);
        if stored.removed {
            scene.instances.push(Instance {
                state: InstanceState::Removed,
                world_box: Aabb::EMPTY,
                ..instance
            });
        } else {
            scene.pending.push(id as u32);
            scene.instances.push(instance);
        }
    }
    scene.build();
    Ok(scene)
}
