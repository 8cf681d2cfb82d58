//! PLY reader (ascii, binary little endian, binary big endian).
//!
//! The header is parsed by `ply_rs_bw`. The payload is decoded here, straight from the file's
//! bytes, into positions and triangles: `ply_rs_bw`'s payload readers build one generic
//! record (a map of named values) per element, which is over 20 times slower on large scans
//! (the 871k-face dragon: about 0.5 s against 20 ms), reports truncation without the
//! element's index, and (in ascii) rejects numbers such as `.5`, `2.` or `nan`. One
//! decoder serves all three encodings (see [`Source`]); it handles every PLY scalar and list
//! type, so no layout needs a fallback.
//!
//! Triangle ids follow the file: faces in file order, polygons with n > 3 vertices
//! fan-triangulated as `(v0,v1,v2), (v0,v2,v3), ...`, the triangles of one face consecutive.
//! Error places count elements from 0 (`"face 0"` is the first face).

use std::path::Path;

use glam::Vec3;
use ply_rs_bw::parser::{ParseError, Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, ElementDef, Encoding, Header, PropertyType, ScalarType};

use super::{MeshError, TriangleMesh};

/// Parses the bytes of a PLY file (`path` names it in errors) as a triangle mesh.
///
/// Accepts ascii and binary (either byte order) files with an element `vertex` holding scalar
/// properties `x`, `y`, `z` of any numeric type, and optionally an element `face` holding an
/// integer list property `vertex_indices` (or `vertex_index`) with any count type. Other
/// elements and properties are skipped. Errors name the place: `"header"` (or the header line)
/// for a missing vertex element or coordinate, `"face K"` for a face with fewer than 3 indices
/// or an index outside the vertices, `"<element> K"` for a truncated file or a bad ascii value.
/// A file without faces is an error ("no triangles").
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<TriangleMesh, MeshError> {
    let (header, body_start) = read_header(path, bytes)?;
    let plan = Plan::new(path, &header)?;
    let body = &bytes[body_start..];
    let (positions, triangles) = match header.encoding {
        Encoding::Ascii => {
            let header_lines = bytes[..body_start].iter().filter(|&&b| b == b'\n').count();
            decode(path, &plan, &mut Ascii::new(body, header_lines))?
        }
        Encoding::BinaryLittleEndian => decode(path, &plan, &mut Binary::<false>::new(body))?,
        Encoding::BinaryBigEndian => decode(path, &plan, &mut Binary::<true>::new(body))?,
    };
    if triangles.is_empty() {
        let reason = if plan.face.is_none() {
            "no triangles (the file has no 'face' element)"
        } else {
            "no triangles (the file has no faces)"
        };
        return Err(MeshError::invalid(path, "file", reason));
    }
    TriangleMesh::from_parts(path.into(), positions, triangles)
}

/// Parses the header with `ply_rs_bw`; returns it and the offset of the payload's first byte.
fn read_header(path: &Path, bytes: &[u8]) -> Result<(Header, usize), MeshError> {
    let mut reader = Reader::new(bytes);
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|e| header_error(path, bytes, &e))?;
    let rest: &[u8] = reader.get_ref();
    let body_start = bytes.len() - rest.len();

    // ply_rs_bw keeps elements and properties in maps keyed by name, so a repeated name would
    // silently drop a declaration and shift every later value. Count the declarations instead.
    let header_text = String::from_utf8_lossy(&bytes[..body_start]);
    let declared = |word: &str| {
        header_text
            .lines()
            .filter(|l| l.split_whitespace().next() == Some(word))
            .count()
    };
    let properties: usize = header.elements.values().map(|e| e.properties.len()).sum();
    if declared("element") != header.elements.len() || declared("property") != properties {
        return Err(MeshError::invalid(
            path,
            "header",
            "an element or property name is declared twice",
        ));
    }
    Ok((header, body_start))
}

/// A header error from `ply_rs_bw`, on one line: its first sentence (the rest is a parser
/// dump) followed by the offending header line, quoted.
fn header_error(path: &Path, bytes: &[u8], error: &ParseError) -> MeshError {
    let text = error.to_string();
    let Some(line) = error.line() else {
        return MeshError::invalid(path, "header", text.replace(['\n', '\t'], " "));
    };
    let text = text
        .strip_prefix(&format!("Line {line}: "))
        .unwrap_or(&text);
    let first = text.lines().next().unwrap_or_default().trim();
    let source_line = bytes
        .split(|&b| b == b'\n')
        .nth(line.saturating_sub(1))
        .map(|l| {
            String::from_utf8_lossy(l)
                .trim()
                .chars()
                .take(80)
                .collect::<String>()
        })
        .filter(|l| !l.is_empty());
    let reason = match source_line {
        Some(l) => format!("{first} \"{l}\""),
        None => first.to_string(),
    };
    MeshError::invalid(path, format!("header line {line}"), reason)
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Num {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Num {
    fn from_ply(t: &ScalarType) -> Self {
        match t {
            ScalarType::Char => Num::I8,
            ScalarType::UChar => Num::U8,
            ScalarType::Short => Num::I16,
            ScalarType::UShort => Num::U16,
            ScalarType::Int => Num::I32,
            ScalarType::UInt => Num::U32,
            ScalarType::Float => Num::F32,
            ScalarType::Double => Num::F64,
        }
    }

    /// Size in bytes in a binary payload.
    fn size(self) -> usize {
        match self {
            Num::I8 | Num::U8 => 1,
            Num::I16 | Num::U16 => 2,
            Num::I32 | Num::U32 | Num::F32 => 4,
            Num::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Num::F32 | Num::F64)
    }

    fn name(self) -> &'static str {
        match self {
            Num::I8 => "char",
            Num::U8 => "uchar",
            Num::I16 => "short",
            Num::U16 => "ushort",
            Num::I32 => "int",
            Num::U32 => "uint",
            Num::F32 => "float",
            Num::F64 => "double",
        }
    }
}

/// What the decoder does with a property.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Use {
    Skip,
    /// Coordinate 0, 1 or 2 of a vertex.
    Coord(usize),
    /// The vertex index list of a face.
    Indices,
}

#[derive(Clone, Copy, Debug)]
enum Shape {
    Scalar(Num),
    List { count: Num, item: Num },
}

#[derive(Clone, Copy, Debug)]
struct Property {
    shape: Shape,
    used: Use,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Vertex,
    Face,
    Other,
}

/// How to decode one element block of the payload.
#[derive(Debug)]
struct ElementPlan {
    name: String,
    count: usize,
    role: Role,
    properties: Vec<Property>,
    /// Bytes of one record in a binary payload when it has no lists.
    fixed_size: Option<usize>,
    /// The fewest bytes one record can take (binary) or ascii characters (a digit and a
    /// separator per value), to cap allocations by the file size.
    min_binary_size: usize,
    min_ascii_size: usize,
}

/// The payload layout, checked against what a mesh needs.
#[derive(Debug)]
struct Plan {
    elements: Vec<ElementPlan>,
    vertex_count: usize,
    /// Position of the face element in `elements`.
    face: Option<usize>,
}

impl Plan {
    /// Checks the header: a `vertex` element with scalar `x`, `y`, `z` and, when present, a
    /// `face` element with an integer list `vertex_indices` or `vertex_index`.
    fn new(path: &Path, header: &Header) -> Result<Self, MeshError> {
        let header_error = |reason: String| MeshError::invalid(path, "header", reason);
        let vertex = header
            .elements
            .get("vertex")
            .ok_or_else(|| header_error("no 'vertex' element".into()))?;
        for axis in ["x", "y", "z"] {
            match vertex.properties.get(axis).map(|p| &p.data_type) {
                Some(PropertyType::Scalar(_)) => {}
                Some(PropertyType::List(..)) => {
                    return Err(header_error(format!(
                        "vertex property '{axis}' is a list, expected a number"
                    )))
                }
                None => {
                    return Err(header_error(format!(
                        "the 'vertex' element has no property '{axis}'"
                    )))
                }
            }
        }
        if u32::try_from(vertex.count).is_err() {
            return Err(header_error(format!(
                "{} vertices is more than 32-bit indices can address",
                vertex.count
            )));
        }
        let face_list = match header.elements.get("face") {
            None => None,
            Some(face) => {
                let name = ["vertex_indices", "vertex_index"]
                    .into_iter()
                    .find(|n| face.properties.contains_key(*n))
                    .ok_or_else(|| {
                        header_error(
                            "the 'face' element has no property 'vertex_indices' or \
                             'vertex_index'"
                                .into(),
                        )
                    })?;
                match &face.properties[name].data_type {
                    PropertyType::List(_, item) if Num::from_ply(item).is_integer() => {}
                    PropertyType::List(_, item) => {
                        return Err(header_error(format!(
                            "face property '{name}' holds {}, expected integers",
                            Num::from_ply(item).name()
                        )))
                    }
                    PropertyType::Scalar(_) => {
                        return Err(header_error(format!(
                            "face property '{name}' is a number, expected a list"
                        )))
                    }
                }
                Some(name)
            }
        };

        let mut elements = Vec::with_capacity(header.elements.len());
        let mut face = None;
        for element in header.elements.values() {
            let role = match element.name.as_str() {
                "vertex" => Role::Vertex,
                "face" => {
                    face = Some(elements.len());
                    Role::Face
                }
                _ => Role::Other,
            };
            elements.push(element_plan(path, element, role, face_list)?);
        }
        Ok(Self {
            elements,
            vertex_count: vertex.count,
            face,
        })
    }
}

fn element_plan(
    path: &Path,
    element: &ElementDef,
    role: Role,
    face_list: Option<&str>,
) -> Result<ElementPlan, MeshError> {
    let mut properties = Vec::with_capacity(element.properties.len());
    for (name, def) in &element.properties {
        let shape = match &def.data_type {
            PropertyType::Scalar(t) => Shape::Scalar(Num::from_ply(t)),
            PropertyType::List(count, item) => {
                let count = Num::from_ply(count);
                if !count.is_integer() {
                    return Err(MeshError::invalid(
                        path,
                        "header",
                        format!(
                            "list property '{}.{name}' has a {} length, expected an integer type",
                            element.name,
                            count.name()
                        ),
                    ));
                }
                Shape::List {
                    count,
                    item: Num::from_ply(item),
                }
            }
        };
        let used = match (role, name.as_str()) {
            (Role::Vertex, "x") => Use::Coord(0),
            (Role::Vertex, "y") => Use::Coord(1),
            (Role::Vertex, "z") => Use::Coord(2),
            (Role::Face, n) if Some(n) == face_list => Use::Indices,
            _ => Use::Skip,
        };
        properties.push(Property { shape, used });
    }
    let fixed_size = properties
        .iter()
        .map(|p| match p.shape {
            Shape::Scalar(t) => Some(t.size()),
            Shape::List { .. } => None,
        })
        .sum();
    let min_binary_size = properties
        .iter()
        .map(|p| match p.shape {
            Shape::Scalar(t) | Shape::List { count: t, .. } => t.size(),
        })
        .sum();
    Ok(ElementPlan {
        name: element.name.clone(),
        count: element.count,
        role,
        min_ascii_size: 2 * properties.len(),
        properties,
        fixed_size,
        min_binary_size,
    })
}

/// Why a value could not be read.
enum Fault {
    /// The payload ended early.
    End,
    /// An ascii value that does not parse, or an ascii line with values left over.
    Bad(String),
}

/// Values of the payload, one record (element) at a time.
trait Source {
    /// Binary sources can skip fixed-size records without reading them.
    const BINARY: bool;
    /// Bytes (or characters) of payload not yet read.
    fn remaining(&self) -> usize;
    /// Moves to the next record.
    fn begin_record(&mut self) -> Result<(), Fault>;
    /// The next value, of type `t`. Integers up to 32 bits are exact in `f64`.
    fn value(&mut self, t: Num) -> Result<f64, Fault>;
    /// Checks that the record has been read completely.
    fn end_record(&mut self) -> Result<(), Fault>;
    /// Skips `bytes` bytes (binary sources only; at most [`Source::remaining`]).
    fn skip(&mut self, bytes: usize);
    /// Text added to an error place, such as the ascii line number.
    fn location(&self) -> String;
}

/// Binary payload; `BIG` selects big-endian.
struct Binary<'a, const BIG: bool> {
    data: &'a [u8],
    pos: usize,
}

impl<'a, const BIG: bool> Binary<'a, BIG> {
    fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    #[inline]
    fn take<const N: usize>(&mut self) -> Result<[u8; N], Fault> {
        let bytes = self
            .data
            .get(self.pos..self.pos + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or(Fault::End)?;
        self.pos += N;
        Ok(bytes)
    }
}

macro_rules! decode_number {
    ($self:ident, $ty:ty) => {{
        let bytes = $self.take::<{ std::mem::size_of::<$ty>() }>()?;
        let v = if BIG {
            <$ty>::from_be_bytes(bytes)
        } else {
            <$ty>::from_le_bytes(bytes)
        };
        f64::from(v)
    }};
}

impl<const BIG: bool> Source for Binary<'_, BIG> {
    const BINARY: bool = true;

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    #[inline]
    fn begin_record(&mut self) -> Result<(), Fault> {
        Ok(())
    }

    #[inline]
    fn value(&mut self, t: Num) -> Result<f64, Fault> {
        Ok(match t {
            Num::I8 => decode_number!(self, i8),
            Num::U8 => decode_number!(self, u8),
            Num::I16 => decode_number!(self, i16),
            Num::U16 => decode_number!(self, u16),
            Num::I32 => decode_number!(self, i32),
            Num::U32 => decode_number!(self, u32),
            Num::F32 => decode_number!(self, f32),
            Num::F64 => decode_number!(self, f64),
        })
    }

    #[inline]
    fn end_record(&mut self) -> Result<(), Fault> {
        Ok(())
    }

    fn skip(&mut self, bytes: usize) {
        self.pos = (self.pos + bytes).min(self.data.len());
    }

    fn location(&self) -> String {
        String::new()
    }
}

/// Ascii payload: one record per non-blank line, values separated by whitespace.
struct Ascii<'a> {
    rest: &'a [u8],
    /// Number of the current line in the file (1-based).
    line: usize,
    tokens: std::str::SplitAsciiWhitespace<'a>,
}

impl<'a> Ascii<'a> {
    fn new(body: &'a [u8], header_lines: usize) -> Self {
        Self {
            rest: body,
            line: header_lines,
            tokens: "".split_ascii_whitespace(),
        }
    }
}

impl<'a> Source for Ascii<'a> {
    const BINARY: bool = false;

    fn remaining(&self) -> usize {
        self.rest.len()
    }

    fn begin_record(&mut self) -> Result<(), Fault> {
        loop {
            if self.rest.is_empty() {
                return Err(Fault::End);
            }
            let len = self
                .rest
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.rest.len(), |i| i + 1);
            let (line, rest) = self.rest.split_at(len);
            self.rest = rest;
            self.line += 1;
            let text: &'a str = std::str::from_utf8(line)
                .map_err(|_| Fault::Bad("line is not valid UTF-8".into()))?;
            if !text.trim_ascii().is_empty() {
                self.tokens = text.split_ascii_whitespace();
                return Ok(());
            }
        }
    }

    fn value(&mut self, t: Num) -> Result<f64, Fault> {
        let token = self
            .tokens
            .next()
            .ok_or_else(|| Fault::Bad(format!("line ends where a {} was expected", t.name())))?;
        let bad = || Fault::Bad(format!("cannot read '{token}' as a {}", t.name()));
        if t.is_integer() {
            // Exact for every PLY integer type; range-checked like a binary value would be.
            let v: i64 = match token.parse() {
                Ok(v) => v,
                // Some writers print integers as "3.0": accept whole numbers only.
                Err(_) => match token.parse::<f64>() {
                    Ok(f) if f.fract() == 0.0 && f.abs() < 1e15 => f as i64,
                    _ => return Err(bad()),
                },
            };
            let (lo, hi) = match t {
                Num::I8 => (i8::MIN.into(), i8::MAX.into()),
                Num::U8 => (0, u8::MAX.into()),
                Num::I16 => (i16::MIN.into(), i16::MAX.into()),
                Num::U16 => (0, u16::MAX.into()),
                Num::I32 => (i32::MIN.into(), i32::MAX.into()),
                _ => (0, u32::MAX.into()),
            };
            if !(lo..=hi).contains(&v) {
                return Err(Fault::Bad(format!(
                    "{v} does not fit in a {} (range {lo}..={hi})",
                    t.name()
                )));
            }
            Ok(v as f64)
        } else {
            token.parse().map_err(|_| bad())
        }
    }

    fn end_record(&mut self) -> Result<(), Fault> {
        let extra = self.tokens.clone().count();
        if extra > 0 {
            return Err(Fault::Bad(format!(
                "{extra} more value(s) on the line than the header declares"
            )));
        }
        Ok(())
    }

    fn skip(&mut self, _bytes: usize) {}

    fn location(&self) -> String {
        format!(" (line {})", self.line)
    }
}

/// Decodes every element of the payload in header order, keeping vertex coordinates and face
/// index lists; returns positions (one per vertex) and fan-triangulated faces.
fn decode<S: Source>(
    path: &Path,
    plan: &Plan,
    src: &mut S,
) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), MeshError> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face: Vec<f64> = Vec::new();

    for element in &plan.elements {
        if element.properties.is_empty() {
            // Nothing stored: no bytes in binary, nothing but blank lines in ascii.
            continue;
        }
        // Never trust the declared count for allocation: cap it by what the file can hold.
        let min_size = if S::BINARY {
            element.min_binary_size
        } else {
            element.min_ascii_size
        };
        let capacity = element.count.min(src.remaining() / min_size.max(1));
        match element.role {
            Role::Vertex => positions.reserve(capacity),
            Role::Face => triangles.reserve(capacity),
            Role::Other => {
                if let (true, Some(size)) = (S::BINARY, element.fixed_size) {
                    // Unused records of fixed size: skip the whole block at once.
                    let block = element.count.checked_mul(size);
                    match block {
                        Some(bytes) if bytes <= src.remaining() => {
                            src.skip(bytes);
                            continue;
                        }
                        _ => return Err(truncated(path, element, src.remaining() / size)),
                    }
                }
            }
        }

        for k in 0..element.count {
            let mut xyz = [0.0f64; 3];
            face.clear();
            match read_record(src, element, &mut xyz, &mut face) {
                Ok(()) => {}
                Err(Fault::End) => return Err(truncated(path, element, k)),
                Err(Fault::Bad(reason)) => {
                    let place = format!("{} {k}{}", element.name, src.location());
                    return Err(MeshError::invalid(path, place, reason));
                }
            }
            match element.role {
                Role::Vertex => {
                    positions.push(Vec3::new(xyz[0] as f32, xyz[1] as f32, xyz[2] as f32))
                }
                Role::Face => fan(&face, plan.vertex_count, &mut triangles).map_err(|reason| {
                    MeshError::invalid(path, format!("face {k}{}", src.location()), reason)
                })?,
                Role::Other => {}
            }
        }
    }
    Ok((positions, triangles))
}

/// Reads one record of `element`: its coordinates into `xyz` (vertex) or its vertex indices
/// into `face` (face); every other value is read and dropped.
#[inline]
fn read_record<S: Source>(
    src: &mut S,
    element: &ElementPlan,
    xyz: &mut [f64; 3],
    face: &mut Vec<f64>,
) -> Result<(), Fault> {
    src.begin_record()?;
    for property in &element.properties {
        match (property.shape, property.used) {
            (Shape::Scalar(t), Use::Coord(axis)) => xyz[axis] = src.value(t)?,
            (Shape::Scalar(t), _) => {
                src.value(t)?;
            }
            (Shape::List { count, item }, used) => {
                let n = src.value(count)?;
                if n < 0.0 {
                    return Err(Fault::Bad(format!("negative list length {n}")));
                }
                // `count` is an integer type, so `n` is a whole number below 2^32.
                for _ in 0..n as usize {
                    let v = src.value(item)?;
                    if used == Use::Indices {
                        face.push(v);
                    }
                }
            }
        }
    }
    src.end_record()
}

/// The error for a payload that ends inside record `k` of `element`.
fn truncated(path: &Path, element: &ElementPlan, k: usize) -> MeshError {
    MeshError::invalid(
        path,
        format!("{} {k}", element.name),
        format!(
            "unexpected end of file: the file is truncated (the header declares {} '{}' elements)",
            element.count, element.name
        ),
    )
}

/// Appends the fan triangulation of one face after checking its indices.
fn fan(face: &[f64], vertex_count: usize, triangles: &mut Vec<[u32; 3]>) -> Result<(), String> {
    if face.len() < 3 {
        return Err(format!(
            "face has {} vertex indices; a face needs at least 3",
            face.len()
        ));
    }
    let mut indices = [0u32; 3];
    for (slot, &v) in face.iter().enumerate() {
        if v < 0.0 {
            return Err(format!("negative vertex index {v}"));
        }
        if v >= vertex_count as f64 {
            return Err(format!(
                "vertex index {v} out of range (the file has {vertex_count} vertices)"
            ));
        }
        // In range and integral (PLY indices are integer types), so the cast is exact.
        let v = v as u32;
        match slot {
            0 | 1 => indices[slot] = v,
            _ => {
                indices[2] = v;
                triangles.push(indices);
                indices[1] = v;
            }
        }
    }
    Ok(())
}
