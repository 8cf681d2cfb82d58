//! `SceneError`: what a scene refuses, naming the argument and the reason.

use std::fmt;

use super::{InstanceId, MeshId};

/// Why a transform or an instance was refused. Never a panic: every check of user input in
/// [`Scene`](super::Scene) and [`InstanceTransform`](super::InstanceTransform) answers with one
/// of these.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SceneError {
    /// An entry of the transform's matrix is NaN or infinite (`row`, `column` of the 3×4 or 4×4
    /// matrix, counted from 0).
    NonFiniteTransform {
        row: usize,
        column: usize,
        value: f64,
    },
    /// The bottom row of a 4×4 transform is not `0 0 0 1`: the map is projective, not affine.
    NotAffine { bottom_row: [f64; 4] },
    /// The linear part is singular or too close to it: `|det| < 2^-40 · s³` with `s` its largest
    /// entry magnitude (see [`InstanceTransform::new`](super::InstanceTransform::new)), or its
    /// inverse overflows.
    SingularTransform {
        determinant: f64,
        largest_entry: f64,
    },
    /// `add_instance` was given a mesh id the scene did not hand out.
    UnknownMesh { mesh: MeshId, meshes: usize },
    /// An instance id the scene did not hand out (`instances` is how many it did).
    UnknownInstance {
        instance: InstanceId,
        instances: usize,
    },
    /// An instance id that was removed ([`Scene::remove_instance`](super::Scene::remove_instance));
    /// it stays a hole and is never handed out again.
    RemovedInstance { instance: InstanceId },
    /// `set_mesh_positions` was given `given` positions for a mesh of `expected` vertices.
    PositionCount {
        mesh: MeshId,
        expected: usize,
        given: usize,
    },
    /// `set_mesh_positions` was given a coordinate that is not finite or beyond
    /// `±MAX_COORDINATE` ([`crate::mesh::MAX_COORDINATE`]) at `vertex`.
    InvalidPosition { mesh: MeshId, vertex: usize },
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SceneError::NonFiniteTransform { row, column, value } => write!(
                f,
                "transform: entry at row {row}, column {column} is {value}; every entry must be finite"
            ),
            SceneError::NotAffine { bottom_row } => write!(
                f,
                "transform: the bottom row of a 4x4 matrix must be [0, 0, 0, 1], not {bottom_row:?}"
            ),
            SceneError::SingularTransform {
                determinant,
                largest_entry,
            } => write!(
                f,
                "transform: the linear part is singular or nearly so (determinant {determinant:e}, \
                 largest entry {largest_entry:e}; |determinant| must be at least 2^-40 times the \
                 largest entry cubed)"
            ),
            SceneError::UnknownMesh { mesh, meshes } => write!(
                f,
                "mesh: id {} does not exist; the scene has {meshes} mesh(es)",
                mesh.0
            ),
            SceneError::UnknownInstance {
                instance,
                instances,
            } => write!(
                f,
                "instance: id {} does not exist; the scene has handed out {instances} instance id(s)",
                instance.0
            ),
            SceneError::PositionCount {
                mesh,
                expected,
                given,
            } => write!(
                f,
                "positions: {given} given for mesh {}, which has {expected} vertices",
                mesh.0
            ),
            SceneError::InvalidPosition { mesh, vertex } => write!(
                f,
                "positions: vertex {vertex} (mesh {}) is not finite or beyond ±f32::MAX / 2",
                mesh.0
            ),
            SceneError::RemovedInstance { instance } => write!(
                f,
                "instance: id {} was removed; removed ids are never reused",
                instance.0
            ),
        }
    }
}

impl std::error::Error for SceneError {}
