//! The arguments of `hbv.Scene`'s changes, read and checked: the mesh an instance places (and
//! the identity that makes the same object one mesh of the scene), its transform, and instance
//! ids.

use std::sync::Arc;

use hbv::bvh::BuildTree;
use hbv::glam::{DMat4, DVec3, Vec3};
use hbv::scene::{InstanceId, InstanceTransform, MeshId, Scene};
use hbv::TriangleMesh;
use numpy::PyUntypedArrayMethods;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyList, PyTuple};

use crate::arrays::{as_ndarray, float_array, index_array, shape_text, type_name, FloatSlice};
use crate::bvh::PyBvh;
use crate::mesh::{mesh_error, PyMesh};

/// The identity of what `Scene.add` was given as a mesh: one object (an `hbv.Mesh`, an
/// `hbv.BVH`, a trimesh mesh), or the two arrays of a `(vertices, faces)` pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MeshKey([usize; 2]);

impl MeshKey {
    /// The key of `obj`, with the objects it names: the caller keeps them alive for as long as
    /// the key is used, so that their addresses are not handed to other objects.
    pub fn of(obj: &Bound<'_, PyAny>) -> (Self, Vec<Py<PyAny>>) {
        match pair(obj) {
            Some((vertices, faces)) => (
                Self([vertices.as_ptr() as usize, faces.as_ptr() as usize]),
                vec![vertices.unbind(), faces.unbind()],
            ),
            None => (Self([obj.as_ptr() as usize, 0]), vec![obj.clone().unbind()]),
        }
    }
}

/// The two items of a tuple or list of length 2.
fn pair<'py>(obj: &Bound<'py, PyAny>) -> Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let is_pair = (obj.is_instance_of::<PyTuple>() || obj.is_instance_of::<PyList>())
        && obj.len().ok() == Some(2);
    if !is_pair {
        return None;
    }
    Some((obj.get_item(0).ok()?, obj.get_item(1).ok()?))
}

/// A mesh to add to a scene, read from `Scene.add`'s first argument.
pub enum NewMesh {
    /// An `hbv.BVH`: its mesh with the tree already built, laid out without building again.
    Built(Arc<TriangleMesh>, Arc<BuildTree>),
    /// An `hbv.Mesh`, or float32 vertices.
    Single(Arc<TriangleMesh>),
    /// Float64 vertices (or integers): stored in float32 relative to their own centre, so that
    /// a mesh far from the origin keeps its precision (`Scene::add_mesh_f64`).
    Double(Vec<DVec3>, Vec<[u32; 3]>),
}

impl NewMesh {
    /// Reads an `hbv.BVH`, an `hbv.Mesh`, a `(vertices, faces)` pair, or an object with
    /// `vertices` and `faces` attributes (a `trimesh.Trimesh`).
    pub fn read(obj: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(bvh) = obj.cast::<PyBvh>() {
            let (mesh, tree) = bvh.get().mesh_and_tree();
            return Ok(NewMesh::Built(mesh.clone(), tree.clone()));
        }
        if let Ok(mesh) = obj.cast::<PyMesh>() {
            return Ok(NewMesh::Single(mesh.get().mesh.clone()));
        }
        if let Some((vertices, faces)) = pair(obj) {
            return Self::from_arrays(&vertices, &faces);
        }
        match (obj.getattr("vertices"), obj.getattr("faces")) {
            (Ok(vertices), Ok(faces)) => Self::from_arrays(&vertices, &faces),
            _ => Err(PyTypeError::new_err(format!(
                "mesh: expected an hbv.Mesh, an hbv.BVH, a (vertices, faces) pair or an object \
                 with vertices and faces (a trimesh.Trimesh), got {}",
                type_name(obj)
            ))),
        }
    }

    fn from_arrays(vertices: &Bound<'_, PyAny>, faces: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (floats, rows) = float_array("vertices", vertices, Some(3), None)?;
        let faces = index_array("faces", faces)?;
        match floats.values() {
            FloatSlice::F32(values) => {
                let positions = values.chunks_exact(3).map(Vec3::from_slice).collect();
                let mesh = TriangleMesh::new(positions, faces).map_err(mesh_error)?;
                Ok(NewMesh::Single(Arc::new(mesh)))
            }
            FloatSlice::F64(values) => {
                let positions: Vec<DVec3> = values.chunks_exact(3).map(DVec3::from_slice).collect();
                debug_assert_eq!(positions.len(), rows);
                Ok(NewMesh::Double(positions, faces))
            }
        }
    }

    /// Adds the mesh to `scene` (no instance yet).
    pub fn add_to(self, scene: &mut Scene) -> PyResult<MeshId> {
        match self {
            NewMesh::Built(mesh, tree) => Ok(scene.add_built_mesh((*mesh).clone(), &tree)),
            NewMesh::Single(mesh) => Ok(scene.add_mesh((*mesh).clone())),
            NewMesh::Double(positions, faces) => {
                scene.add_mesh_f64(&positions, &faces).map_err(mesh_error)
            }
        }
    }
}

/// A transform: `None` for the identity, or a (4, 4) matrix acting on column vectors
/// `(x, y, z, 1)` (bottom row `0 0 0 1`) or its top (3, 4) rows, of any float or integer dtype
/// (read as float64). Checked: finite, affine and invertible (`InstanceTransform::new`).
pub fn read_transform(obj: Option<&Bound<'_, PyAny>>) -> PyResult<InstanceTransform> {
    const NAME: &str = "transform";
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(InstanceTransform::IDENTITY);
    };
    // Converted once: an object NumPy reads twice could answer two shapes.
    let array = as_ndarray(NAME, obj)?;
    let shape = array.shape().to_vec();
    if shape != [4, 4] && shape != [3, 4] {
        return Err(PyValueError::new_err(format!(
            "{NAME}: expected shape (4, 4) or (3, 4), got {}",
            shape_text(&shape)
        )));
    }
    let (floats, rows) = float_array(NAME, array.as_any(), Some(4), None)?;
    let values: Vec<f64> = match floats.values() {
        FloatSlice::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
        FloatSlice::F64(v) => v.to_vec(),
    };
    let checked = if rows == 4 {
        // Row-major in NumPy; glam's matrices are column-major.
        let matrix = DMat4::from_cols_array(&values.try_into().expect("shape (4, 4)")).transpose();
        InstanceTransform::from_mat4(matrix)
    } else {
        let row = |i: usize| -> [f64; 4] { values[4 * i..4 * i + 4].try_into().expect("4") };
        InstanceTransform::from_rows([row(0), row(1), row(2)])
    };
    // The library's message starts with "transform: ".
    checked.map_err(|e| PyValueError::new_err(e.to_string()))
}

/// An instance id: a Python integer that the scene handed out (`issued` of them), not a bool.
/// Whether it was removed is the scene's to say.
pub fn instance_id(obj: &Bound<'_, PyAny>, issued: usize) -> PyResult<InstanceId> {
    if obj.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err(format!(
            "instance: expected an integer id, got {}",
            type_name(obj)
        )));
    }
    let id: i128 = obj.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "instance: expected an integer id, got {}",
            type_name(obj)
        ))
    })?;
    u32::try_from(id).map(InstanceId).map_err(|_| {
        PyValueError::new_err(format!(
            "instance: id {id} does not exist; the scene has handed out {issued} instance id(s)"
        ))
    })
}
