//! The OBJ, PLY and glTF loaders on small generated files, broken files, and (when present)
//! the shared test scenes.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::Vec3;
use hbv::{MeshError, TriangleMesh};
use tempfile::TempDir;

fn write(dir: &TempDir, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Loads a file that must fail and returns the message, checking it names the file.
fn error_of(path: &Path) -> String {
    let err = match TriangleMesh::load(path) {
        Ok(mesh) => panic!(
            "{} loaded ({} triangles) but should fail",
            path.display(),
            mesh.triangle_count()
        ),
        Err(err) => err,
    };
    let message = err.to_string();
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(
        message.contains(name),
        "message does not name the file: {message}"
    );
    message
}

fn assert_mentions(message: &str, words: &[&str]) {
    for word in words {
        assert!(message.contains(word), "message lacks {word:?}: {message}");
    }
}

fn corners(mesh: &TriangleMesh, t: usize) -> [Vec3; 3] {
    mesh.indices()[t].map(|i| mesh.positions()[i as usize])
}

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

// ---------------------------------------------------------------- OBJ

#[test]
fn obj_fans_polygons_in_file_order_across_objects() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "polygons.obj",
        "# quad, pentagon (relative indices), triangle\n\
         mtllib missing.mtl\n\
         o first\n\
         v 0 0 0\n\
         v 1 0 0\n\
         v 1 1 0\n\
         v 0 1 0\n\
         vt 0 0\n\
         vn 0 0 1\n\
         f 1/1/1 2/1/1 3/1/1 4/1/1\n\
         g second\n\
         usemtl red\n\
         v 2 0 0\n\
         v 3 0 0\n\
         v 3 1 0\n\
         v 2.5 2 0\n\
         v 2 1 0\n\
         f -5 -4 -3 -2 -1\n\
         l 1 2 3\n\
         o third\n\
         f 1 3 4\n",
    );
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(mesh.triangle_count(), 6);
    assert_eq!(
        mesh.indices(),
        &[
            [0, 1, 2],
            [0, 2, 3],
            [4, 5, 6],
            [4, 6, 7],
            [4, 7, 8],
            [0, 2, 3]
        ]
    );
    let p = [
        v(0., 0., 0.),
        v(1., 0., 0.),
        v(1., 1., 0.),
        v(0., 1., 0.),
        v(2., 0., 0.),
        v(3., 0., 0.),
        v(3., 1., 0.),
        v(2.5, 2., 0.),
        v(2., 1., 0.),
    ];
    let expected = [
        [p[0], p[1], p[2]],
        [p[0], p[2], p[3]],
        [p[4], p[5], p[6]],
        [p[4], p[6], p[7]],
        [p[4], p[7], p[8]],
        [p[0], p[2], p[3]],
    ];
    for (t, want) in expected.iter().enumerate() {
        assert_eq!(&corners(&mesh, t), want, "triangle {t}");
    }
    assert_eq!(mesh.degenerate_count(), 0);
}

#[test]
fn obj_keeps_degenerate_triangles_and_reads_w_and_colours() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "degenerate.obj",
        "v 0 0 0\nv 2 0 0 2\nv 0 1 0 0.5 0.5 0.5\nf 1 2 3\nf 1 1 2\n",
    );
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(mesh.triangle_count(), 2);
    assert_eq!(mesh.degenerate_count(), 1);
    assert_eq!(
        corners(&mesh, 0),
        [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)]
    );
}

#[test]
fn obj_bad_number_names_the_line() {
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "badnum.obj", "v 0 0 0\nv 1 0 0\nv 1 2 abc\nf 1 2 3\n");
    let message = error_of(&path);
    assert_mentions(&message, &["line 3", "cannot parse vertex position", "abc"]);
}

#[test]
fn obj_bad_face_token_names_the_line() {
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "badface.obj", "v 0 0 0\nv 1 0 0\nv 1 2 0\nf 1 2 x\n");
    let message = error_of(&path);
    assert_mentions(&message, &["line 4", "cannot parse face"]);
}

#[test]
fn obj_index_out_of_range_names_the_line() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "range.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n# next one is bad\nf 1 2 99\n",
    );
    let message = error_of(&path);
    assert_mentions(&message, &["line 6", "99", "out of range", "3 vertices"]);

    let path = write(&dir, "zero.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n");
    assert_mentions(&error_of(&path), &["line 4", "index 0"]);

    let path = write(
        &dir,
        "relative.obj",
        "v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 1 1 0\n",
    );
    assert_mentions(
        &error_of(&path),
        &["line 3", "-3", "before the first vertex"],
    );
}

#[test]
fn obj_face_with_two_vertices_is_an_error() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "short.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2\n",
    );
    assert_mentions(&error_of(&path), &["line 5", "at least 3"]);
}

#[test]
fn obj_non_finite_vertex_names_the_line() {
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
    assert_mentions(&error_of(&path), &["line 3", "not finite"]);
}

#[test]
fn obj_without_faces_has_no_triangles() {
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "empty.obj", "");
    assert_mentions(&error_of(&path), &["file", "no triangles"]);
    let path = write(&dir, "points.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2 3\n");
    assert_mentions(&error_of(&path), &["no triangles"]);
}

#[test]
fn missing_file_is_an_io_error() {
    let dir = TempDir::new().unwrap();
    for name in ["missing.obj", "missing.ply", "missing.gltf", "missing.glb"] {
        let path = dir.path().join(name);
        let err = TriangleMesh::load(&path).unwrap_err();
        assert!(matches!(err, MeshError::Io { .. }), "{name}: {err}");
        assert_mentions(&err.to_string(), &[name, "cannot read"]);
    }
}

// ---------------------------------------------------------------- PLY

/// A PLY file: `header` lines (without `ply` and `end_header`) and a binary or ascii body.
fn ply(header: &[&str], body: impl AsRef<[u8]>) -> Vec<u8> {
    let mut out = b"ply\n".to_vec();
    for line in header {
        out.extend_from_slice(line.as_bytes());
        out.push(b'\n');
    }
    out.extend_from_slice(b"end_header\n");
    out.extend_from_slice(body.as_ref());
    out
}

const UNIT_SQUARE: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];

fn le_triangles_body(vertices: &[[f32; 3]], faces: &[[i32; 3]]) -> Vec<u8> {
    let mut body = Vec::new();
    for p in vertices {
        for c in p {
            body.extend_from_slice(&c.to_le_bytes());
        }
    }
    for f in faces {
        body.push(3);
        for i in f {
            body.extend_from_slice(&i.to_le_bytes());
        }
    }
    body
}

const LE_TRIANGLES_HEADER: [&str; 8] = [
    "format binary_little_endian 1.0",
    "element vertex 4",
    "property float x",
    "property float y",
    "property float z",
    "element face 2",
    "property list uchar int vertex_indices",
    "comment end",
];

#[test]
fn ply_ascii_with_extra_properties_and_elements() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "ascii.ply",
        ply(
            &[
                "format ascii 1.0",
                "comment made by hand",
                "element vertex 5",
                "property float confidence",
                "property float x",
                "property float y",
                "property double z",
                "property list uchar float normals",
                "element face 3",
                "property uchar flags",
                "property list uchar int vertex_indices",
                "element edge 1",
                "property int vertex1",
                "property int vertex2",
            ],
            "0.5 0 0 0 0\n\
             0.5 1 0 0 3 0 0 1\n\
             \n\
             0.5 1 1 0 0\n\
             0.5 .5 2. 1e0 0\n\
             0.5 -1.5 0 0 0\n\
             7 3 0 1 2\n\
             7 4 0 2 3 4\n\
             7 3 4 4 4\n\
             0 1\n",
        ),
    );
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(
        mesh.indices(),
        &[[0, 1, 2], [0, 2, 3], [0, 3, 4], [4, 4, 4]]
    );
    assert_eq!(mesh.positions()[3], v(0.5, 2.0, 1.0));
    assert_eq!(mesh.positions()[4], v(-1.5, 0.0, 0.0));
    assert_eq!(mesh.degenerate_count(), 1);
}

#[test]
fn ply_binary_little_endian_double_coords_uint_indices() {
    let dir = TempDir::new().unwrap();
    let points: [[f64; 3]; 4] = [
        [0.1, 0.2, 0.3],
        [1.0, -2.0, 3.5],
        [1e-3, 4.0, -7.25],
        [5.0, 6.0, 7.0],
    ];
    let mut body = Vec::new();
    for (k, p) in points.iter().enumerate() {
        body.push(k as u8); // uchar red
        for c in p {
            body.extend_from_slice(&c.to_le_bytes());
        }
    }
    for face in [[0u32, 1, 2], [3, 2, 1]] {
        body.push(3);
        for i in face {
            body.extend_from_slice(&i.to_le_bytes());
        }
        body.extend_from_slice(&1.5f32.to_le_bytes()); // float quality
    }
    let path = write(
        &dir,
        "le.ply",
        ply(
            &[
                "format binary_little_endian 1.0",
                "element vertex 4",
                "property uchar red",
                "property double x",
                "property double y",
                "property double z",
                "element face 2",
                "property list uchar uint vertex_indices",
                "property float quality",
            ],
            body,
        ),
    );
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(mesh.indices(), &[[0, 1, 2], [3, 2, 1]]);
    for (k, p) in points.iter().enumerate() {
        assert_eq!(
            mesh.positions()[k],
            v(p[0] as f32, p[1] as f32, p[2] as f32)
        );
    }
}

#[test]
fn ply_binary_big_endian() {
    let dir = TempDir::new().unwrap();
    let mut body = Vec::new();
    for p in UNIT_SQUARE {
        for c in p {
            body.extend_from_slice(&c.to_be_bytes());
        }
        body.extend_from_slice(&(-3i16).to_be_bytes()); // short extra
    }
    // One quad with a ushort count and short indices.
    body.extend_from_slice(&4u16.to_be_bytes());
    for i in [0i16, 1, 2, 3] {
        body.extend_from_slice(&i.to_be_bytes());
    }
    let path = write(
        &dir,
        "be.ply",
        ply(
            &[
                "format binary_big_endian 1.0",
                "element vertex 4",
                "property float32 x",
                "property float32 y",
                "property float32 z",
                "property int16 extra",
                "element face 1",
                "property list ushort short vertex_indices",
            ],
            body,
        ),
    );
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(mesh.indices(), &[[0, 1, 2], [0, 2, 3]]);
    assert_eq!(mesh.positions()[2], v(1., 1., 0.));
}

#[test]
fn ply_quads_are_fanned_in_order() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "quads.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 6",
                "property float x",
                "property float y",
                "property float z",
                "element face 2",
                "property list uchar int vertex_index",
            ],
            "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n2 1 0\n4 0 1 2 3\n4 1 4 5 2\n",
        ),
    );
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(
        mesh.indices(),
        &[[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]]
    );
}

#[test]
fn ply_truncated_binary_names_the_element() {
    let dir = TempDir::new().unwrap();
    let mut bytes = ply(
        &LE_TRIANGLES_HEADER,
        le_triangles_body(&UNIT_SQUARE, &[[0, 1, 2], [0, 2, 3]]),
    );
    bytes.truncate(bytes.len() - 5);
    let path = write(&dir, "truncated.ply", &bytes);
    assert_mentions(
        &error_of(&path),
        &["face 1", "truncated", "unexpected end of file"],
    );

    bytes.truncate(bytes.len() - 39); // 30 payload bytes: inside vertex 2
    let path = write(&dir, "truncated_vertices.ply", &bytes);
    assert_mentions(&error_of(&path), &["vertex 2", "truncated"]);
}

#[test]
fn ply_truncated_ascii_names_the_element() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "short.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 3",
                "property float x",
                "property float y",
                "property float z",
                "element face 2",
                "property list uchar int vertex_indices",
            ],
            "0 0 0\n1 0 0\n1 1 0\n3 0 1 2\n",
        ),
    );
    assert_mentions(&error_of(&path), &["face 1", "truncated"]);
}

#[test]
fn ply_face_index_out_of_range() {
    let dir = TempDir::new().unwrap();
    let bytes = ply(
        &LE_TRIANGLES_HEADER,
        le_triangles_body(&UNIT_SQUARE, &[[0, 1, 2], [0, 2, 4]]),
    );
    let path = write(&dir, "range.ply", bytes);
    assert_mentions(
        &error_of(&path),
        &["face 1", "index 4", "out of range", "4 vertices"],
    );

    let bytes = ply(
        &LE_TRIANGLES_HEADER,
        le_triangles_body(&UNIT_SQUARE, &[[0, -1, 2], [0, 2, 3]]),
    );
    let path = write(&dir, "negative.ply", bytes);
    assert_mentions(&error_of(&path), &["face 0", "negative vertex index -1"]);
}

#[test]
fn ply_face_with_two_indices_is_an_error() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "twoindices.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 3",
                "property float x",
                "property float y",
                "property float z",
                "element face 2",
                "property list uchar int vertex_indices",
            ],
            "0 0 0\n1 0 0\n1 1 0\n3 0 1 2\n2 0 1\n",
        ),
    );
    assert_mentions(&error_of(&path), &["face 1 (line 14)", "at least 3"]);
}

#[test]
fn ply_bad_ascii_value_names_element_and_line() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "badvalue.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 3",
                "property float x",
                "property float y",
                "property float z",
                "element face 1",
                "property list uchar int vertex_indices",
            ],
            "0 0 0\n1 abc 0\n1 1 0\n3 0 1 2\n",
        ),
    );
    assert_mentions(&error_of(&path), &["vertex 1 (line 11)", "abc", "float"]);
}

#[test]
fn ply_without_vertex_element_or_coordinate() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "novertex.ply",
        ply(
            &[
                "format ascii 1.0",
                "element point 1",
                "property float x",
                "element face 0",
                "property list uchar int vertex_indices",
            ],
            "0\n",
        ),
    );
    assert_mentions(&error_of(&path), &["header", "no 'vertex' element"]);

    let path = write(
        &dir,
        "noz.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 1",
                "property float x",
                "property float y",
            ],
            "0 0\n",
        ),
    );
    assert_mentions(&error_of(&path), &["header", "no property 'z'"]);

    let path = write(
        &dir,
        "noindices.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 1",
                "property float x",
                "property float y",
                "property float z",
                "element face 1",
                "property list uchar int corners",
            ],
            "0 0 0\n3 0 0 0\n",
        ),
    );
    assert_mentions(&error_of(&path), &["header", "vertex_indices"]);
}

#[test]
fn ply_bad_header_names_the_line() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "badheader.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty floot x\nend_header\n0\n",
    );
    assert_mentions(&error_of(&path), &["header line 4"]);
    let path = write(&dir, "empty.ply", "");
    assert_mentions(&error_of(&path), &["header", "end of file"]);
    let path = write(&dir, "notply.ply", "v 0 0 0\n");
    assert_mentions(
        &error_of(&path),
        &["header line 1", "magic number", "v 0 0 0"],
    );
    let path = write(
        &dir,
        "twice.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n\
         property float y\nproperty float z\nend_header\n0 0 0 0\n",
    );
    assert_mentions(&error_of(&path), &["header", "declared twice"]);
}

#[test]
fn ply_huge_declared_count_in_tiny_file_fails_fast() {
    let dir = TempDir::new().unwrap();
    let mut header = LE_TRIANGLES_HEADER;
    header[5] = "element face 2147483648";
    let bytes = ply(&header, le_triangles_body(&UNIT_SQUARE, &[[0, 1, 2]]));
    let path = write(&dir, "huge.ply", bytes);
    let start = Instant::now();
    let message = error_of(&path);
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "took {:?}",
        start.elapsed()
    );
    assert_mentions(&message, &["face 1", "truncated", "2147483648"]);

    // The same in ascii, and with a huge vertex count.
    let path = write(
        &dir,
        "huge_ascii.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 4294967295",
                "property float x",
                "property float y",
                "property float z",
            ],
            "0 0 0\n",
        ),
    );
    let start = Instant::now();
    let message = error_of(&path);
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "took {:?}",
        start.elapsed()
    );
    assert_mentions(&message, &["vertex 1", "truncated"]);
}

#[test]
fn ply_nan_vertex_is_not_finite() {
    let dir = TempDir::new().unwrap();
    let mut square = UNIT_SQUARE;
    square[2][1] = f32::NAN;
    let bytes = ply(
        &LE_TRIANGLES_HEADER,
        le_triangles_body(&square, &[[0, 1, 2], [0, 2, 3]]),
    );
    let path = write(&dir, "nan.ply", bytes);
    assert_mentions(&error_of(&path), &["vertex 2", "not finite"]);
}

#[test]
fn ply_without_faces_has_no_triangles() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "cloud.ply",
        ply(
            &[
                "format ascii 1.0",
                "element vertex 1",
                "property float x",
                "property float y",
                "property float z",
            ],
            "0 0 0\n",
        ),
    );
    assert_mentions(&error_of(&path), &["file", "no triangles"]);
}

// ---------------------------------------------------------------- glTF

fn base64(data: &[u8]) -> String {
    const TABLE: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(TABLE[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn f32_bytes(values: &[[f32; 3]]) -> Vec<u8> {
    values
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect()
}

#[test]
fn gltf_applies_node_transforms_in_scene_order() {
    let triangle = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]];
    let mut buffer = f32_bytes(&triangle); // 36 bytes
    buffer.extend(f32_bytes(&UNIT_SQUARE)); // 48 bytes at 36
    for i in [0u16, 1, 2, 0, 2, 3] {
        buffer.extend_from_slice(&i.to_le_bytes()); // 12 bytes at 84
    }
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 1,
  "scenes": [{{"nodes": [0]}}, {{"nodes": [1, 0]}}],
  "nodes": [
    {{"mesh": 0, "translation": [10, 0, 0]}},
    {{"translation": [0, 5, 0], "scale": [2, 2, 2], "children": [2]}},
    {{"mesh": 1, "translation": [1, 0, 0]}}
  ],
  "meshes": [
    {{"primitives": [{{"attributes": {{"POSITION": 0}}}},
                     {{"attributes": {{"POSITION": 0}}, "mode": 1}}]}},
    {{"primitives": [{{"attributes": {{"POSITION": 1}}, "indices": 2}}]}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 4, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 84}},
    {{"buffer": 0, "byteOffset": 84, "byteLength": 12}}
  ],
  "buffers": [{{"byteLength": {len},
               "uri": "data:application/octet-stream;base64,{data}"}}]
}}"#,
        len = buffer.len(),
        data = base64(&buffer)
    );
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "scene.gltf", json);
    let mesh = TriangleMesh::load(&path).unwrap();
    assert_eq!(mesh.triangle_count(), 3);
    // Scene 1 lists node 1 (parent: translate (0,5,0), scale 2; child: translate (1,0,0))
    // before node 0 (translate (10,0,0)); the LINES primitive is skipped.
    let q = |x: f32, y: f32| v(2. * (x + 1.), 2. * y + 5., 0.);
    assert_eq!(corners(&mesh, 0), [q(0., 0.), q(1., 0.), q(1., 1.)]);
    assert_eq!(corners(&mesh, 1), [q(0., 0.), q(1., 1.), q(0., 1.)]);
    assert_eq!(
        corners(&mesh, 2),
        [v(10., 0., 0.), v(11., 0., 0.), v(10., 1., 0.)]
    );
}

/// A GLB container: 12-byte header, JSON chunk (space padded), BIN chunk (zero padded).
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes()); // "JSON"
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes()); // "BIN\0"
    out.extend_from_slice(&bin);
    out
}

#[test]
fn glb_strips_and_fans_without_a_scene() {
    let points = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
    let mut bin = f32_bytes(&points); // 48 bytes
    bin.extend_from_slice(&[0u8, 1, 2, 3]); // u8 indices at 48
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "meshes": [{{"primitives": [
    {{"attributes": {{"POSITION": 0}}, "mode": 5}},
    {{"attributes": {{"POSITION": 0}}, "indices": 1, "mode": 6}},
    {{"attributes": {{"POSITION": 0}}, "mode": 0}}
  ]}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5121, "count": 4, "type": "SCALAR"}}
  ],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 4}}
  ],
  "buffers": [{{"byteLength": {len}}}]
}}"#,
        len = bin.len()
    );
    let dir = TempDir::new().unwrap();
    let path = write(&dir, "shapes.glb", glb(&json, &bin));
    let mesh = TriangleMesh::load(&path).unwrap();
    // Strip: (v0,v1,v2), (v1,v3,v2); fan (glTF rule p_i = v_{i+1}, v_{i+2}, v_0), offset by
    // the 4 positions of the first primitive; the POINTS primitive is skipped.
    assert_eq!(
        mesh.indices(),
        &[[0, 1, 2], [1, 3, 2], [5, 6, 4], [6, 7, 4]]
    );
    assert_eq!(mesh.positions().len(), 8);
    assert_eq!(
        corners(&mesh, 3),
        [v(0., 1., 0.), v(1., 1., 0.), v(0., 0., 0.)]
    );
}

#[test]
fn gltf_broken_json() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "broken.gltf",
        r#"{"asset": {"version": "2.0"}, "meshes": ["#,
    );
    assert_mentions(&error_of(&path), &["file", "not valid glTF"]);
}

#[test]
fn gltf_without_triangles() {
    let dir = TempDir::new().unwrap();
    let bin = f32_bytes(&[[0., 0., 0.]]);
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}},
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "mode": 0}}]}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3",
                  "min": [0, 0, 0], "max": [0, 0, 0]}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 12}}],
  "buffers": [{{"byteLength": 12, "uri": "data:application/octet-stream;base64,{}"}}]}}"#,
        base64(&bin)
    );
    let path = write(&dir, "points.gltf", json);
    assert_mentions(&error_of(&path), &["file", "no triangles"]);

    let path = write(&dir, "nothing.gltf", r#"{"asset": {"version": "2.0"}}"#);
    assert_mentions(&error_of(&path), &["no triangles"]);
}

#[test]
fn gltf_missing_external_buffer() {
    let dir = TempDir::new().unwrap();
    let json = r#"{"asset": {"version": "2.0"},
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]}],
  "bufferViews": [{"buffer": 0, "byteLength": 36}],
  "buffers": [{"byteLength": 36, "uri": "geometry.bin"}]}"#;
    let path = write(&dir, "external.gltf", json);
    assert_mentions(&error_of(&path), &["buffer 0", "geometry.bin"]);

    // With the file present it loads, relative to the .gltf's folder.
    write(
        &dir,
        "geometry.bin",
        f32_bytes(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]),
    );
    assert_eq!(TriangleMesh::load(&path).unwrap().triangle_count(), 1);
}

#[test]
fn gltf_index_out_of_range_names_the_primitive() {
    let dir = TempDir::new().unwrap();
    let mut bin = f32_bytes(&[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]]);
    bin.extend_from_slice(&[0, 1, 7, 0]);
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}},
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                  "min": [0, 0, 0], "max": [1, 1, 0]}},
                {{"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}},
                  {{"buffer": 0, "byteOffset": 36, "byteLength": 3}}],
  "buffers": [{{"byteLength": 40, "uri": "data:application/octet-stream;base64,{}"}}]}}"#,
        base64(&bin)
    );
    let path = write(&dir, "badindex.gltf", json);
    assert_mentions(
        &error_of(&path),
        &["mesh 0 primitive 0", "index 7", "out of range"],
    );
}

#[test]
fn gltf_node_cycle_is_an_error() {
    let dir = TempDir::new().unwrap();
    let path = write(
        &dir,
        "cycle.gltf",
        r#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}],
            "nodes": [{"children": [1]}, {"children": [0]}]}"#,
    );
    assert_mentions(&error_of(&path), &["node 0", "cycle"]);
}

// ---------------------------------------------------------------- shared scenes

#[test]
fn shared_scenes_load_with_their_documented_counts() {
    let dir = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/scenes"
    ));
    if !dir.is_dir() {
        eprintln!("skipping: {} not found", dir.display());
        return;
    }
    let expected = [
        ("cornell_box.ply", 36),
        ("spot.ply", 5856),
        ("teapot.ply", 6320),
        ("bunny.ply", 69451),
        ("igea.ply", 268686),
        ("dragon.ply", 871414),
    ];
    for (name, triangles) in expected {
        let path = dir.join(name);
        let start = Instant::now();
        let mesh = TriangleMesh::load(&path).unwrap();
        eprintln!(
            "{name}: {} triangles, {} vertices, {} degenerate, loaded in {:?}",
            mesh.triangle_count(),
            mesh.positions().len(),
            mesh.degenerate_count(),
            start.elapsed()
        );
        assert_eq!(mesh.triangle_count(), triangles, "{name}");
        if name == "dragon.ply" {
            assert_eq!(mesh.degenerate_count(), 108, "dragon degenerate triangles");
        }
    }
}
