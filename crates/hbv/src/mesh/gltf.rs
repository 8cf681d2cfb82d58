//! glTF 2.0 reader (`.gltf` JSON with embedded or external buffers, and binary `.glb`), built on
//! the `gltf` crate.
//!
//! The mesh is the scene's geometry flattened in world space: the default scene (else scene 0;
//! with no scene at all, every mesh untransformed) is walked depth-first, nodes in the order
//! listed and children in order, and every triangle primitive of a node's mesh is appended in
//! primitive order with the node's world transform applied (f32 math). Triangle ids follow
//! that order. Point and line primitives are skipped; images are never loaded.
//!
//! The walk ([`walk_default_scene`]) and the reading of a mesh's primitives
//! ([`PrimitiveReader`]) are shared with the scene loader (`scene/gltf.rs`), which walks the
//! same nodes with f64 transforms and reads each mesh once, untransformed.

use std::path::Path;

use glam::{Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use gltf::{buffer, Document, Gltf, Mesh, Node, Semantic};

use super::{MeshError, TriangleMesh};

/// Parses the bytes of a `.gltf` or `.glb` file (`path` names it in errors) as one triangle
/// mesh in world space. Buffers in other files are read from `folder`; without one (bytes
/// that never were a file) they are an error.
///
/// Accepts primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (converted with the
/// glTF rules), indexed (u8/u16/u32) or not, with float VEC3 positions. External buffers are
/// read relative to `folder`. Invalid JSON, a missing buffer, unreadable accessor
/// data, an index past the primitive's positions or a node cycle is an error naming the place;
/// a scene without triangles is an error ("no triangles").
pub(super) fn parse(
    path: &Path,
    bytes: &[u8],
    folder: Option<&Path>,
) -> Result<TriangleMesh, MeshError> {
    let (document, buffers) = document_and_buffers(path, bytes, folder)?;

    let reader = PrimitiveReader::new(path, &buffers);
    let mut out = MeshParts::default();
    walk_default_scene(
        path,
        &document,
        Mat4::IDENTITY,
        |parent, node| Ok(*parent * Mat4::from_cols_array_2d(&node.transform().matrix())),
        |_, mesh, world| reader.append_mesh(&mesh, world, TriangleModes::All, &mut out),
    )?;

    if out.triangles.is_empty() {
        return Err(MeshError::invalid(
            path,
            "file",
            "no triangles (the scene has no triangle primitives)",
        ));
    }
    TriangleMesh::from_parts(path.into(), out.positions, out.triangles)
}

/// The document and its buffers, read as [`parse`] reads them: the GLB header, every
/// primitive's POSITION accessor and every buffer checked.
pub(crate) fn document_and_buffers(
    path: &Path,
    bytes: &[u8],
    folder: Option<&Path>,
) -> Result<(Document, Vec<buffer::Data>), MeshError> {
    let not_gltf =
        |e: gltf::Error| MeshError::invalid(path, "file", format!("not valid glTF: {e}"));
    check_glb_length(path, bytes)?;
    // Validation happens in two steps because the `gltf` crate's validator (gltf-json 1.4.1,
    // `primitive_validate_hook`) indexes the accessor list with a primitive's POSITION index
    // before checking it: a file naming a missing accessor would panic (found by fuzzing).
    let Gltf { document, blob } = Gltf::from_slice_without_validation(bytes).map_err(not_gltf)?;
    check_position_accessors(path, document.as_json())?;
    let document = Document::from_json(document.into_json()).map_err(not_gltf)?;
    let buffers = load_buffers(path, folder, &document, blob)?;
    Ok((document, buffers))
}

/// A glTF file's document and buffers, read and checked as [`TriangleMesh::load`] reads them,
/// for a caller that walks the document itself (the renderer's glTF scenes): devices refused,
/// buffers read from regular files only and only their declared bytes, and every accessor of
/// every mesh primitive (POSITION and indices) checked ([`check_accessor`]), so that the
/// `gltf` crate's reader can be trusted with them.
pub(super) fn read_checked(path: &Path) -> Result<(Document, Vec<buffer::Data>), MeshError> {
    let bytes = super::read_mesh_file(path)?;
    let (document, buffers) = document_and_buffers(path, &bytes, Some(super::folder_of(path)))?;
    let buffer_bytes = buffers.iter().map(|b| b.len()).sum();
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            if let Some(positions) = primitive.get(&Semantic::Positions) {
                check_accessor(path, buffer_bytes, &positions, "POSITION")?;
            }
            if let Some(indices) = primitive.indices() {
                check_accessor(path, buffer_bytes, &indices, "indices")?;
            }
        }
    }
    Ok((document, buffers))
}

/// A GLB must declare a total length of at least its 12-byte header (the `gltf` crate
/// subtracts 12 from it unchecked).
fn check_glb_length(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    if let Some(length) = bytes.strip_prefix(b"glTF").and_then(|b| b.get(4..8)) {
        let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]);
        if length < 12 {
            return Err(MeshError::invalid(
                path,
                "GLB header",
                format!("declares a total length of {length} bytes, less than the header's 12"),
            ));
        }
    }
    Ok(())
}

/// Every primitive's POSITION must name an accessor that exists (checked before the `gltf`
/// crate's validation, which would index the accessor list with it).
fn check_position_accessors(path: &Path, root: &gltf::json::Root) -> Result<(), MeshError> {
    use gltf::json::mesh::Semantic as JsonSemantic;
    use gltf::json::validation::Checked;
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive
                .attributes
                .get(&Checked::Valid(JsonSemantic::Positions));
            if let Some(index) = position.filter(|i| i.value() >= accessors) {
                return Err(MeshError::invalid(
                    path,
                    format!("mesh {m} primitive {p}"),
                    format!(
                        "POSITION names accessor {}, but the file has {accessors} accessors",
                        index.value()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Reads every buffer: the GLB `BIN` chunk, a `data:` URI, or a file in `folder`.
fn load_buffers(
    path: &Path,
    folder: Option<&Path>,
    document: &Document,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<buffer::Data>, MeshError> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let place = format!("buffer {}", buffer.index());
        let what = match buffer.source() {
            buffer::Source::Bin => "the GLB binary chunk".to_string(),
            buffer::Source::Uri(uri) if uri.starts_with("data:") => "its data URI".to_string(),
            buffer::Source::Uri(uri) => format!("'{uri}'"),
        };
        if folder.is_none()
            && matches!(buffer.source(), buffer::Source::Uri(uri) if !uri.starts_with("data:"))
        {
            return Err(MeshError::invalid(
                path,
                place,
                format!("cannot load {what}: external files are not read when parsing bytes"),
            ));
        }
        let data = match (buffer.source(), folder) {
            (buffer::Source::Uri(uri), Some(folder)) if !uri.starts_with("data:") => {
                read_buffer_file(folder, uri, buffer.length())
                    .map(buffer::Data)
                    .map_err(|e| {
                        MeshError::invalid(path, &place, format!("cannot load {what}: {e}"))
                    })?
            }
            (source, _) => {
                buffer::Data::from_source_and_blob(source, folder, &mut blob).map_err(|e| {
                    MeshError::invalid(path, &place, format!("cannot load {what}: {e}"))
                })?
            }
        };
        if data.len() < buffer.length() {
            return Err(MeshError::invalid(
                path,
                place,
                format!(
                    "{what} holds {} bytes, but the buffer is declared with {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The first `length` bytes of the file a buffer's URI names: relative to `folder`, or a
/// `file:` URI, percent-decoded. Only a regular file is read, and only the bytes the buffer
/// declares (the `gltf` crate's reader reads whatever it is given to its end: `/dev/zero` for
/// ever, and it panics on a percent-escape that does not decode to UTF-8).
fn read_buffer_file(folder: &Path, uri: &str, length: usize) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let (scheme, rest) = match uri.split_once(':') {
        Some(("file", rest)) => ("file", rest.strip_prefix("//").unwrap_or(rest)),
        Some((scheme, _)) => return Err(format!("the URI scheme '{scheme}:' is not supported")),
        None => ("", uri),
    };
    let decoded = urlencoding::decode(rest)
        .map_err(|_| "its percent-escapes do not decode to UTF-8 text".to_string())?;
    let file = if scheme == "file" {
        std::path::PathBuf::from(&*decoded)
    } else {
        folder.join(&*decoded)
    };
    let opened = std::fs::File::open(&file).map_err(|e| format!("{}: {e}", file.display()))?;
    let meta = opened
        .metadata()
        .map_err(|e| format!("{}: {e}", file.display()))?;
    if !meta.is_file() {
        return Err(format!("{} is not a regular file", file.display()));
    }
    if meta.len() < length as u64 {
        return Err(format!(
            "{} holds {} bytes, but the buffer is declared with {length}",
            file.display(),
            meta.len()
        ));
    }
    let mut data = Vec::with_capacity(length);
    opened
        .take(length as u64)
        .read_to_end(&mut data)
        .map_err(|e| format!("{}: {e}", file.display()))?;
    Ok(data)
}

/// Positions and triangles being assembled from a glTF file's primitives.
#[derive(Default)]
pub(crate) struct MeshParts {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Which primitive modes give triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TriangleModes {
    /// TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (the flattened mesh of
    /// [`TriangleMesh::load`]).
    All,
    /// TRIANGLES (mode 4) only, as `RAYS.md`'s "Scenes (glTF)" defines a scene's meshes.
    TrianglesOnly,
}

impl TriangleModes {
    fn accepts(self, mode: Mode) -> bool {
        match self {
            TriangleModes::All => matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ),
            TriangleModes::TrianglesOnly => mode == Mode::Triangles,
        }
    }
}

/// A step of the depth-first walk.
enum Visit<'a, T> {
    /// Process a node below a parent with this world transform.
    Enter(Node<'a>, T),
    /// The node's subtree is done.
    Leave(usize),
}

/// Walks the default scene (else scene 0) depth-first in pre-order: roots in the scene's order,
/// children in order (iteratively, so deep hierarchies cannot overflow the stack). A node's
/// world transform is `compose(parent's, node)` (`identity` above the roots); `visit(node,
/// mesh, world)` is called for every node that carries a mesh. A file without any scene visits
/// every mesh once, in order, with `identity` and no node. A node that is its own ancestor is
/// an error naming it.
pub(crate) fn walk_default_scene<'d, T>(
    path: &Path,
    document: &'d Document,
    identity: T,
    mut compose: impl FnMut(&T, &Node<'d>) -> Result<T, MeshError>,
    mut visit: impl FnMut(Option<&Node<'d>>, Mesh<'d>, &T) -> Result<(), MeshError>,
) -> Result<(), MeshError>
where
    T: Clone,
{
    let Some(scene) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    else {
        for mesh in document.meshes() {
            visit(None, mesh, &identity)?;
        }
        return Ok(());
    };
    let roots: Vec<Node<'d>> = scene.nodes().collect();
    let mut on_path = vec![false; document.nodes().len()];
    let mut stack: Vec<Visit<'d, T>> = roots
        .into_iter()
        .rev()
        .map(|node| Visit::Enter(node, identity.clone()))
        .collect();
    while let Some(visit_step) = stack.pop() {
        let (node, parent) = match visit_step {
            Visit::Enter(node, parent) => (node, parent),
            Visit::Leave(index) => {
                on_path[index] = false;
                continue;
            }
        };
        let index = node.index();
        if on_path[index] {
            return Err(MeshError::invalid(
                path,
                format!("node {index}"),
                "the node is its own ancestor (cycle in the node hierarchy)",
            ));
        }
        on_path[index] = true;
        let world = compose(&parent, &node)?;
        if let Some(mesh) = node.mesh() {
            visit(Some(&node), mesh, &world)?;
        }
        stack.push(Visit::Leave(index));
        let children: Vec<Node<'d>> = node.children().collect();
        stack.extend(
            children
                .into_iter()
                .rev()
                .map(|child| Visit::Enter(child, world.clone())),
        );
    }
    Ok(())
}

/// Reads the triangles of a file's mesh primitives, checking each accessor before the `gltf`
/// crate's reader sees it.
pub(crate) struct PrimitiveReader<'a> {
    path: &'a Path,
    buffers: &'a [buffer::Data],
    /// Bytes in all buffers: no honest accessor declares more elements, or a larger offset.
    buffer_bytes: usize,
}

impl<'a> PrimitiveReader<'a> {
    /// A reader of the primitives whose data lies in `buffers` (errors name `path`).
    pub(crate) fn new(path: &'a Path, buffers: &'a [buffer::Data]) -> Self {
        Self {
            path,
            buffers,
            buffer_bytes: buffers.iter().map(|b| b.len()).sum(),
        }
    }

    /// [`check_accessor`] against this file's buffers.
    fn check_accessor(&self, accessor: &gltf::Accessor<'_>, what: &str) -> Result<(), MeshError> {
        check_accessor(self.path, self.buffer_bytes, accessor, what)
    }

    /// Appends the primitives of `mesh` whose mode `modes` accepts to `out`, in order, their
    /// positions transformed by `world` (f32) and their triangles indexing `out.positions`.
    /// Errors name the mesh and primitive (or the accessor) and the reason.
    pub(crate) fn append_mesh(
        &self,
        mesh: &Mesh<'_>,
        world: &Mat4,
        modes: TriangleModes,
        out: &mut MeshParts,
    ) -> Result<(), MeshError> {
        for primitive in mesh.primitives() {
            let mode = primitive.mode();
            if !modes.accepts(mode) {
                continue;
            }
            let place = format!("mesh {} primitive {}", mesh.index(), primitive.index());
            let error = |reason: String| MeshError::invalid(self.path, &place, reason);
            let buffers = self.buffers;
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));

            // Validation guarantees a POSITION accessor; its type is checked here because
            // the reader would misread anything but float VEC3.
            let accessor = primitive
                .get(&Semantic::Positions)
                .ok_or_else(|| error("no POSITION attribute".into()))?;
            if accessor.data_type() != DataType::F32 || accessor.dimensions() != Dimensions::Vec3 {
                return Err(error(format!(
                    "POSITION is {:?} {:?}; only float VEC3 positions are supported",
                    accessor.data_type(),
                    accessor.dimensions()
                )));
            }
            self.check_accessor(&accessor, "POSITION")?;
            let count = accessor.count();
            let base = out.positions.len();
            if count > 0 {
                let positions = reader.read_positions().ok_or_else(|| {
                    error("POSITION data is missing or lies outside its buffer".into())
                })?;
                if *world == Mat4::IDENTITY {
                    out.positions.extend(positions.map(Vec3::from));
                } else {
                    out.positions
                        .extend(positions.map(|p| world.transform_point3(Vec3::from(p))));
                }
            }
            if u32::try_from(out.positions.len()).is_err() {
                return Err(error("more than 2^32 vertices in the scene".into()));
            }

            let vertices: Vec<u32> = match primitive.indices() {
                Some(indices) => {
                    if !matches!(
                        indices.data_type(),
                        DataType::U8 | DataType::U16 | DataType::U32
                    ) {
                        return Err(error(format!(
                            "indices are {:?}; expected unsigned integers",
                            indices.data_type()
                        )));
                    }
                    self.check_accessor(&indices, "indices")?;
                    if indices.count() == 0 {
                        Vec::new()
                    } else {
                        reader
                            .read_indices()
                            .ok_or_else(|| {
                                error("index data is missing or lies outside its buffer".into())
                            })?
                            .into_u32()
                            .collect()
                    }
                }
                None => (0..count as u32).collect(),
            };
            if let Some(&bad) = vertices.iter().find(|&&v| v as usize >= count) {
                return Err(error(format!(
                    "index {bad} out of range (the primitive has {count} positions)"
                )));
            }

            // `base + v` fits: the total vertex count was checked above.
            let at = |v: u32| base as u32 + v;
            let v = &vertices;
            match mode {
                Mode::Triangles => {
                    if !v.len().is_multiple_of(3) {
                        return Err(error(format!(
                            "{} vertices is not a whole number of triangles",
                            v.len()
                        )));
                    }
                    out.triangles
                        .extend(v.chunks_exact(3).map(|t| [at(t[0]), at(t[1]), at(t[2])]));
                }
                // glTF 2.0 spec, 3.7.2.1: p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}.
                Mode::TriangleStrip => {
                    out.triangles
                        .extend((0..v.len().saturating_sub(2)).map(|i| {
                            if i % 2 == 0 {
                                [at(v[i]), at(v[i + 1]), at(v[i + 2])]
                            } else {
                                [at(v[i]), at(v[i + 2]), at(v[i + 1])]
                            }
                        }))
                }
                // glTF 2.0 spec, 3.7.2.1: p_i = {v_{i+1}, v_{i+2}, v_0}.
                Mode::TriangleFan => out.triangles.extend(
                    (0..v.len().saturating_sub(2)).map(|i| [at(v[i + 1]), at(v[i + 2]), at(v[0])]),
                ),
                _ => {}
            }
        }
        Ok(())
    }
}

/// Refuses accessors the `gltf` crate's reader cannot be trusted with: sparse ones (its sparse
/// reader computes `count - 1` unchecked, unwraps the values, and fills an accessor without a
/// buffer view with `count` zeros, however large `count` is), strides shorter than an element
/// (its reader panics), and any declaring more elements, or a larger byte offset, than all
/// buffers (`buffer_bytes`) have bytes (its reader computes `offset + stride * (count - 1)`
/// unchecked).
fn check_accessor(
    path: &Path,
    buffer_bytes: usize,
    accessor: &gltf::Accessor<'_>,
    what: &str,
) -> Result<(), MeshError> {
    let place = format!("accessor {}", accessor.index());
    if accessor.sparse().is_some() {
        return Err(MeshError::invalid(
            path,
            place,
            format!("{what} is a sparse accessor; sparse accessors are not supported"),
        ));
    }
    if accessor.view().is_none() && accessor.count() > 0 {
        return Err(MeshError::invalid(
            path,
            place,
            format!("{what} has no buffer view (its data would be all zeros)"),
        ));
    }
    if let Some(stride) = accessor.view().and_then(|view| view.stride()) {
        // The `gltf` crate's reader panics on a stride shorter than an element.
        if stride < accessor.size() {
            return Err(MeshError::invalid(
                path,
                place,
                format!(
                    "{what}'s buffer view has a byte stride of {stride}, less than its {}-byte elements",
                    accessor.size()
                ),
            ));
        }
    }
    if accessor.count() > buffer_bytes || accessor.offset() > buffer_bytes {
        return Err(MeshError::invalid(
            path,
            place,
            format!(
                "{what} declares {} elements at offset {}, more than the {} bytes of buffers hold",
                accessor.count(),
                accessor.offset(),
                buffer_bytes
            ),
        ));
    }
    Ok(())
}
