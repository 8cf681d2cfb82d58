//! Wavefront OBJ reader (positions and faces only), built on `tobj`.
//!
//! Triangle ids follow the file: every `f` line in file order, polygons with n > 3 vertices
//! fan-triangulated as `(v0,v1,v2), (v0,v2,v3), ...` with the triangles of one polygon
//! consecutive. Objects, groups and materials do not split or reorder anything: the whole file
//! is one mesh. Vertices are numbered in order of first use by a face, as tobj compacts them
//! (vertices no face uses are dropped); this changes no triangle.
//!
//! `tobj` parses the numbers and resolves relative (negative) indices. It is only handed the
//! `v` and `f` lines (every other line is blanked, so line numbers still match), which keeps
//! it from splitting the mesh into models, loading `.mtl` files, reading polylines (`l`) as
//! faces, or failing on texture/normal/colour data this crate never uses.

use std::io::{self, BufRead, Read};
use std::path::Path;

use glam::Vec3;

use super::{MeshError, TriangleMesh, MAX_COORDINATE};

/// Parses the bytes of an OBJ file (`path` names it in errors) as one triangle mesh.
///
/// Accepts `v x y z [w]` (w divides x, y, z) and `v x y z r g b` vertex lines, and `f` lines
/// whose vertices are written `i`, `i/t`, `i//n` or `i/t/n`, with 1-based or negative
/// (relative) position indices. Every other statement is ignored. A face with fewer than three
/// vertices, an unparsable number or an index outside the file's vertices is an error naming
/// the line; a file without faces is an error ("no triangles").
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<TriangleMesh, MeshError> {
    // A UTF-8 byte-order mark (as some Windows editors write) would hide the first statement:
    // a first vertex lost, every index after it off by one.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut reader = GeometryLines::new(bytes);
    // `..Default::default()` covers the fields tobj's optional features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        // Fan triangulation is done here, from `face_arities`, so that faces with fewer than
        // three vertices are reported instead of silently dropped or blown up to triangles.
        triangulate: false,
        // Multi-index mode: one output vertex per distinct position index.
        single_index: false,
        ignore_points: false,
        ignore_lines: false,
        ..Default::default()
    };
    // `mtllib` lines never reach tobj, so the material loader is never called.
    let loaded = tobj::load_obj_buf(&mut reader, &options, |_| Ok(Default::default()));
    let models = match loaded {
        Ok((models, _materials)) => models,
        Err(error) => return Err(tobj_error(path, bytes, error, &mut reader)),
    };

    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Number of `f` lines seen so far, to find the line of a bad face.
    let mut face_number = 0usize;
    for model in models {
        let mesh = model.mesh;
        let base = u32::try_from(positions.len()).map_err(|_| too_many_vertices(path))?;
        positions.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(to_f32(p[0]), to_f32(p[1]), to_f32(p[2]))),
        );
        u32::try_from(positions.len()).map_err(|_| too_many_vertices(path))?;

        // tobj leaves `face_arities` empty when every face is a triangle.
        let arities: Box<dyn Iterator<Item = u32>> = if mesh.face_arities.is_empty() {
            Box::new(std::iter::repeat_n(3, mesh.indices.len() / 3))
        } else {
            Box::new(mesh.face_arities.iter().copied())
        };
        let mut start = 0usize;
        for arity in arities {
            let n = arity as usize;
            if n < 3 {
                return Err(short_face(path, bytes, face_number, n));
            }
            let polygon = mesh.indices.get(start..start + n).ok_or_else(|| {
                MeshError::invalid(path, "file", "tobj returned fewer face indices than faces")
            })?;
            for k in 1..n - 1 {
                triangles.push([base + polygon[0], base + polygon[k], base + polygon[k + 1]]);
            }
            start += n;
            face_number += 1;
        }
    }

    if triangles.is_empty() {
        return Err(MeshError::invalid(
            path,
            "file",
            "no triangles (the file has no faces)",
        ));
    }
    if !positions
        .iter()
        .all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE)
    {
        if let Some(error) = locate_bad_vertex(path, bytes) {
            return Err(error);
        }
    }
    TriangleMesh::from_parts(path.into(), positions, triangles)
}

/// tobj's coordinates are `f32`, or `f64` when some crate in the build enables tobj's `use_f64`.
fn to_f32(x: impl Into<f64>) -> f32 {
    x.into() as f32
}

fn too_many_vertices(path: &Path) -> MeshError {
    MeshError::invalid(path, "file", "more than 2^32 vertices")
}

/// Turns a tobj error into a [`MeshError`] naming the line it happened on.
///
/// Parse errors surface while tobj reads the offending line, so the reader's line count names
/// it. Out-of-range indices are only found once all lines are read; the file is then scanned
/// again (this path only) to find the first bad index.
fn tobj_error<R: BufRead>(
    path: &Path,
    bytes: &[u8],
    error: tobj::LoadError,
    reader: &mut GeometryLines<R>,
) -> MeshError {
    use tobj::LoadError as E;
    if let Some(io_error) = reader.io_error.take() {
        return MeshError::io(path, io_error);
    }
    let line = reader.lines_read.max(1);
    let text = reader.current_line_text();
    let reason = match error {
        E::PositionParseError => format!("cannot parse vertex position {text}"),
        E::ScalingByZeroError => format!("vertex has w = 0 {text}"),
        E::ColorParseError => {
            format!("vertex needs 3 coordinates, optionally w or r g b; got {text}")
        }
        E::FaceParseError => {
            format!("cannot parse face (vertices are written i, i/t, i//n or i/t/n) {text}")
        }
        E::ReadError => format!("line is not valid UTF-8 {text}"),
        E::FaceVertexOutOfBounds => {
            return locate_bad_index(path, bytes).unwrap_or_else(|| {
                MeshError::invalid(path, "file", "a face vertex index is out of range")
            })
        }
        other => return MeshError::invalid(path, "file", other.to_string()),
    };
    MeshError::invalid(path, format!("line {line}"), reason)
}

/// The error for the `face_number`-th face (0-based count of `f` lines) having `n` vertices.
fn short_face(path: &Path, bytes: &[u8], face_number: usize, n: usize) -> MeshError {
    let reason = format!("face has {n} vertices; a face needs at least 3");
    let line = lossy_lines(bytes)
        .enumerate()
        .filter(|(_, l)| keyword(l.as_bytes()) == b"f")
        .nth(face_number)
        .map(|(i, _)| i + 1);
    match line {
        Some(line) => MeshError::invalid(path, format!("line {line}"), reason),
        None => MeshError::invalid(path, format!("face {face_number}"), reason),
    }
}

/// Scans the file for the first face vertex index outside the file's vertices, with tobj's
/// rules: positive indices count from 1 among all `v` lines of the file, negative ones count
/// back from the last `v` line before the face.
fn locate_bad_index(path: &Path, bytes: &[u8]) -> Option<MeshError> {
    let total = lossy_lines(bytes)
        .filter(|l| keyword(l.as_bytes()) == b"v")
        .count();
    let mut seen = 0usize;
    for (i, line) in lossy_lines(bytes).enumerate() {
        match keyword(line.as_bytes()) {
            b"v" => seen += 1,
            b"f" => {
                let words = line.split_whitespace().skip(1);
                for vertex in words.take_while(|w| !w.starts_with('#')) {
                    let parsed = vertex.split('/').next().map(str::parse::<i64>);
                    let reason = if let Some(Ok(index)) = parsed {
                        index_problem(index, seen, total)
                    } else {
                        // tobj reads a vertex without a position index (`f 1 / 2`) as index 0.
                        Some(format!(
                            "cannot parse face vertex \"{vertex}\" (vertices are written \
                             i, i/t, i//n or i/t/n)"
                        ))
                    };
                    if let Some(reason) = reason {
                        return Some(MeshError::invalid(path, format!("line {}", i + 1), reason));
                    }
                }
            }
            _ => {}
        }
    }
    None
}

/// What is wrong with face vertex index `index` (1-based, or negative: relative), if anything,
/// with `seen` vertices before its face and `total` in the file.
fn index_problem(index: i64, seen: usize, total: usize) -> Option<String> {
    if index == 0 {
        Some("vertex index 0 is invalid (OBJ indices start at 1)".to_string())
    } else if index < 0 && index.unsigned_abs() > seen as u64 {
        Some(format!(
            "relative vertex index {index} points before the first vertex \
             ({seen} vertices precede this face)"
        ))
    } else if index > 0 && index as u64 > total as u64 {
        Some(format!(
            "vertex index {index} out of range (the file has {total} vertices)"
        ))
    } else {
        None
    }
}

/// Scans the file for the first `v` line whose position is not finite or beyond
/// [`MAX_COORDINATE`] (as tobj computes it: f32 coordinates, divided by w when there is one),
/// since tobj renumbers the vertices.
fn locate_bad_vertex(path: &Path, bytes: &[u8]) -> Option<MeshError> {
    for (i, line) in lossy_lines(bytes).enumerate() {
        if keyword(line.as_bytes()) != b"v" {
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().skip(1).collect();
        let number = |k: usize| words.get(k).and_then(|w| w.parse::<f32>().ok());
        let w = if words.len() == 4 {
            number(3)
        } else {
            Some(1.0)
        };
        let (Some(x), Some(y), Some(z), Some(w)) = (number(0), number(1), number(2), w) else {
            continue;
        };
        let p = Vec3::new(x / w, y / w, z / w);
        if !p.is_finite() {
            return Some(MeshError::invalid(
                path,
                format!("line {}", i + 1),
                format!("vertex coordinate is not finite: \"{}\"", line.trim()),
            ));
        }
        if p.abs().max_element() > MAX_COORDINATE {
            return Some(MeshError::invalid(
                path,
                format!("line {}", i + 1),
                format!(
                    "vertex coordinate beyond ±{MAX_COORDINATE:e} (f32::MAX / 2): \"{}\"",
                    line.trim()
                ),
            ));
        }
    }
    None
}

/// The file's lines as text (invalid UTF-8 replaced), numbered as `GeometryLines` numbers them:
/// split at `\n`, a final `\r` dropped.
fn lossy_lines(bytes: &[u8]) -> impl Iterator<Item = std::borrow::Cow<'_, str>> {
    bytes
        .strip_suffix(b"\n")
        .unwrap_or(bytes)
        .split(|&b| b == b'\n')
        .map(|line| String::from_utf8_lossy(line.strip_suffix(b"\r").unwrap_or(line)))
}

/// The statement keyword of an OBJ line: its first whitespace-separated word.
fn keyword(line: &[u8]) -> &[u8] {
    let start = line
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(line.len());
    let rest = &line[start..];
    let len = rest
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(rest.len());
    &rest[..len]
}

/// A line-by-line filter in front of tobj: passes `v` and `f` lines, replaces every other line
/// by an empty one (keeping line numbers), drops the colour of `v x y z r g b` lines (tobj
/// fails when only some vertices have one), and counts the lines handed out.
struct GeometryLines<R> {
    inner: R,
    /// The current line as handed to tobj.
    line: Vec<u8>,
    /// How much of `line` tobj has consumed.
    pos: usize,
    /// Buffer for reading the next line.
    spare: Vec<u8>,
    /// Lines read from the file so far; while tobj parses a line, that line's 1-based number.
    lines_read: usize,
    /// A read error from the file (tobj only reports that reading failed).
    io_error: Option<io::Error>,
}

impl<R: BufRead> GeometryLines<R> {
    fn new(inner: R) -> Self {
        Self {
            inner,
            line: Vec::new(),
            pos: 0,
            spare: Vec::new(),
            lines_read: 0,
            io_error: None,
        }
    }

    /// The line being parsed, quoted and shortened, for error messages.
    fn current_line_text(&self) -> String {
        let text = String::from_utf8_lossy(&self.line);
        let text = text.trim();
        let short: String = text.chars().take(60).collect();
        if short.len() < text.len() {
            format!("\"{short}...\"")
        } else {
            format!("\"{short}\"")
        }
    }

    /// Reads the next file line into `line`, filtered.
    /// At the end of the file the last line is kept (for error messages), fully consumed.
    fn next_line(&mut self) -> io::Result<()> {
        self.spare.clear();
        if let Err(e) = self.inner.read_until(b'\n', &mut self.spare) {
            self.io_error = Some(io::Error::new(e.kind(), e.to_string()));
            return Err(e);
        }
        if self.spare.is_empty() {
            self.pos = self.line.len();
            return Ok(());
        }
        std::mem::swap(&mut self.line, &mut self.spare);
        self.pos = 0;
        self.lines_read += 1;
        match keyword(&self.line) {
            b"f" => {}
            b"v" => {
                let words: Vec<&[u8]> = self
                    .line
                    .split(|b| b.is_ascii_whitespace())
                    .filter(|w| !w.is_empty())
                    .collect();
                if words.len() == 7 {
                    let mut xyz = words[..4].join(&b' ');
                    xyz.push(b'\n');
                    self.line = xyz;
                }
            }
            _ => {
                self.line.clear();
                self.line.push(b'\n');
            }
        }
        Ok(())
    }
}

impl<R: BufRead> Read for GeometryLines<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let available = self.fill_buf()?;
        let n = available.len().min(buf.len());
        buf[..n].copy_from_slice(&available[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for GeometryLines<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.pos >= self.line.len() {
            self.next_line()?;
        }
        Ok(&self.line[self.pos..])
    }

    fn consume(&mut self, amount: usize) {
        self.pos = (self.pos + amount).min(self.line.len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_keeps_geometry_and_line_numbers() {
        let text = "o a\nv 1 2 3\nvt 0 0\nv 1 2 3 0.5 0.5 0.5\nusemtl m\nl 1 2 3\nf 1 2 3";
        let mut reader = GeometryLines::new(text.as_bytes());
        let mut out = String::new();
        reader.read_to_string(&mut out).unwrap();
        assert_eq!(out, "\nv 1 2 3\n\nv 1 2 3\n\n\nf 1 2 3");
        assert_eq!(reader.lines_read, 7);
    }

    #[test]
    fn keyword_is_first_word() {
        assert_eq!(keyword(b"  f 1 2 3\n"), b"f");
        assert_eq!(keyword(b"vt 1 2"), b"vt");
        assert_eq!(keyword(b"\n"), b"");
    }
}
