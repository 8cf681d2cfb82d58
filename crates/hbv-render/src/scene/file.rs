//! The TOML scene format (documented in `docs/SCENES.md`).
//!
//! Parsing is in two steps: `serde` reads the file into entries whose values keep their byte
//! spans (`toml::Spanned`), then each entry is checked and turned into scene objects. Either way an
//! error names the file, the line (from the span) and the key.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::Vec3;
use hbv::{MeshError, TriangleMesh};
use serde::Deserialize;
use toml::Spanned;

use super::instance_entry::InstanceEntry;
use super::{RenderSettings, Scene, SceneAssembly, SceneError, Transform};
use crate::camera::Camera;
use crate::light::Light;
use crate::material::{Material, Surface};

/// Most pixels on a side, samples per pixel, and light samples a scene may ask for: far beyond
/// any sensible render, small enough that sizes never overflow.
const MAX_SIDE: i64 = 1 << 15;
const MAX_SPP: i64 = 1 << 16;
const MAX_LIGHT_SAMPLES: i64 = 1 << 12;
const MAX_DEPTH: i64 = 64;

pub(super) type V3 = Spanned<Triple>;

/// Three numbers, exactly (serde's `[f32; 3]` stops reading after three and lets a fourth pass
/// unnoticed).
#[derive(Clone, Copy)]
pub(super) struct Triple(pub(super) [f32; 3]);

impl<'de> Deserialize<'de> for Triple {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let numbers = Vec::<f32>::deserialize(deserializer)?;
        <[f32; 3]>::try_from(numbers.as_slice())
            .map(Triple)
            .map_err(|_| serde::de::Error::invalid_length(numbers.len(), &"3 numbers"))
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    render: RenderEntry,
    camera: Option<Spanned<CameraEntry>>,
    #[serde(default)]
    materials: BTreeMap<String, Spanned<MaterialEntry>>,
    #[serde(default)]
    mesh: Vec<Spanned<MeshEntry>>,
    #[serde(default)]
    light: Vec<Spanned<LightEntry>>,
    #[serde(default)]
    instance: Vec<Spanned<InstanceEntry>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RenderEntry {
    width: Option<Spanned<i64>>,
    height: Option<Spanned<i64>>,
    spp: Option<Spanned<i64>>,
    max_depth: Option<Spanned<i64>>,
    background: Option<V3>,
    ambient: Option<V3>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraEntry {
    position: V3,
    look_at: V3,
    up: Option<V3>,
    fov: Spanned<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialEntry {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    color: Option<V3>,
    specular: Option<V3>,
    exponent: Option<Spanned<f32>>,
    ior: Option<Spanned<f32>>,
    emission: Option<V3>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshEntry {
    file: Spanned<String>,
    pub(super) name: Option<String>,
    material: Option<Spanned<String>>,
    translate: Option<V3>,
    rotate: Option<V3>,
    scale: Option<Spanned<Scale>>,
    smooth: Option<bool>,
    place: Option<bool>,
}

impl MeshEntry {
    /// The name `[[instance]]` tables use for it: `name`, else `file` as written.
    pub(super) fn name(&self) -> &str {
        self.name.as_deref().unwrap_or(self.file.get_ref())
    }
}

/// What `[[instance]]` tables need of a `[[mesh]]` they place.
pub(super) struct PlacedMesh {
    /// The scene's mesh (files named twice are loaded once).
    pub(super) id: u32,
    pub(super) material: u32,
    pub(super) smooth: bool,
    /// The `[[mesh]]`'s own placement, applied before an instance's.
    pub(super) transform: Transform,
}

/// `scale = k` or `scale = [x, y, z]`.
pub(super) enum Scale {
    Uniform(f32),
    PerAxis(Triple),
}

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Numbers;
        impl<'de> serde::de::Visitor<'de> for Numbers {
            type Value = Scale;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or 3 numbers")
            }
            fn visit_f64<E>(self, k: f64) -> Result<Scale, E> {
                Ok(Scale::Uniform(k as f32))
            }
            fn visit_i64<E>(self, k: i64) -> Result<Scale, E> {
                Ok(Scale::Uniform(k as f32))
            }
            fn visit_u64<E>(self, k: u64) -> Result<Scale, E> {
                Ok(Scale::Uniform(k as f32))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Scale, A::Error> {
                let mut numbers = Vec::new();
                while let Some(x) = seq.next_element::<f32>()? {
                    numbers.push(x);
                }
                <[f32; 3]>::try_from(numbers.as_slice())
                    .map(|a| Scale::PerAxis(Triple(a)))
                    .map_err(|_| serde::de::Error::invalid_length(numbers.len(), &self))
            }
        }
        deserializer.deserialize_any(Numbers)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightEntry {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    position: Option<V3>,
    direction: Option<V3>,
    corner: Option<V3>,
    edge_u: Option<V3>,
    edge_v: Option<V3>,
    color: Option<V3>,
    intensity: Option<Spanned<f32>>,
    samples: Option<Spanned<i64>>,
    visible: Option<bool>,
}

/// Reads a scene file; meshes are found relative to the file's folder. A `.gltf` or `.glb`
/// file is read as a whole scene with its own camera, lights and materials
/// ([`super::load_gltf_scene`]).
pub fn load_scene(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("gltf") | Some("glb")) {
        return super::load_gltf_scene(path);
    }
    let io_error = |error| SceneError::Io {
        file: path.to_path_buf(),
        error,
    };
    refuse_devices(path).map_err(io_error)?;
    let bytes = std::fs::read(path).map_err(io_error)?;
    let source = utf8_text(bytes, path)?;
    let folder = path.parent().unwrap_or(Path::new("."));
    parse_scene(&source, path, &|mesh: &Path| {
        TriangleMesh::load(folder.join(mesh))
    })
}

/// Refuses a device or a socket (through links), which would be read for ever (`/dev/zero`), as
/// the mesh loader does; pipes (`<(...)`) are read.
fn refuse_devices(path: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = std::fs::metadata(path)?.file_type();
        if kind.is_char_device() || kind.is_block_device() || kind.is_socket() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a device or a socket, not a scene file",
            ));
        }
    }
    let _ = path;
    Ok(())
}

/// `bytes` as text, or the place of the first byte that is not UTF-8. (`read_to_string` said
/// only "stream did not contain valid UTF-8", with no place, and the report repeated it.)
fn utf8_text(bytes: Vec<u8>, path: &Path) -> Result<String, SceneError> {
    String::from_utf8(bytes).map_err(|e| {
        let bytes = e.as_bytes();
        let offset = e.utf8_error().valid_up_to();
        let before = &bytes[..offset];
        let line_start = before
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        SceneError::NotUtf8 {
            file: path.to_path_buf(),
            line: before.iter().filter(|&&b| b == b'\n').count() + 1,
            column: offset - line_start + 1,
            offset,
            byte: bytes[offset],
        }
    })
}

/// Reads a scene from its TOML `source`, as if from the file `path` (named in errors); each
/// mesh's `file` is handed to `load_mesh` as written in the scene. [`load_scene`] loads them
/// from disk, relative to the scene's folder; the fuzz target hands back a built-in mesh, so
/// that any text exercises the whole scene reader without touching files.
pub fn parse_scene(
    source: &str,
    path: &Path,
    load_mesh: &dyn Fn(&Path) -> Result<TriangleMesh, MeshError>,
) -> Result<Scene, SceneError> {
    let ctx = Context {
        file: path.to_path_buf(),
        source,
    };
    let parsed: SceneFile = toml::from_str(source).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        ctx.error_at(&span, &ctx.key_at(span.start), e.message().trim())
    })?;
    ctx.build(parsed, load_mesh)
}

/// The file being read, for error messages.
pub(super) struct Context<'a> {
    file: PathBuf,
    source: &'a str,
}

impl Context<'_> {
    pub(super) fn line_of(&self, offset: usize) -> usize {
        let end = offset.min(self.source.len());
        self.source.as_bytes()[..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1
    }

    pub(super) fn error_at(
        &self,
        span: &Range<usize>,
        key: &str,
        reason: impl Into<String>,
    ) -> SceneError {
        SceneError::Invalid {
            file: self.file.clone(),
            line: self.line_of(span.start),
            key: key.to_string(),
            reason: reason.into(),
        }
    }

    /// The dotted key at `offset` for errors that serde reports with a span only: the table
    /// header above it (`[[mesh]]` entries numbered from 0) and the key on its line.
    fn key_at(&self, offset: usize) -> String {
        let offset = offset.min(self.source.len());
        let line_start = self.source[..offset].rfind('\n').map_or(0, |i| i + 1);
        let line_end = self.source[offset..]
            .find('\n')
            .map_or(self.source.len(), |i| offset + i);
        let line = self.source[line_start..line_end].trim();
        let mut table = String::new();
        let mut counts: BTreeMap<String, usize> = BTreeMap::new();
        for l in self.source[..line_end].lines() {
            let l = l.trim();
            if let Some(name) = l.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
                let name = name.trim().to_string();
                let n = counts.entry(name.clone()).or_insert(0);
                table = format!("{name}[{n}]");
                *n += 1;
            } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.split(']').next()) {
                table = name.trim().to_string();
            }
        }
        let key = if line.starts_with('[') {
            String::new()
        } else {
            line.split('=').next().unwrap_or("").trim().to_string()
        };
        match (table.is_empty(), key.is_empty()) {
            (_, true) if table.is_empty() => "(top level)".into(),
            (_, true) => table,
            (true, false) => key,
            (false, false) => format!("{table}.{key}"),
        }
    }

    fn build(
        &self,
        file: SceneFile,
        load_mesh: &dyn Fn(&Path) -> Result<TriangleMesh, MeshError>,
    ) -> Result<Scene, SceneError> {
        let settings = self.settings(&file.render)?;
        let camera = match &file.camera {
            Some(c) => self.camera(c)?,
            None => {
                return Err(self.error_at(&(0..0), "camera", "the scene has no [camera] table"))
            }
        };
        let mut materials = Vec::new();
        let mut material_index = BTreeMap::new();
        for (name, entry) in &file.materials {
            material_index.insert(name.clone(), materials.len() as u32);
            materials.push(self.material(name, entry)?);
        }
        let mut lights = Vec::new();
        let mut assembly = SceneAssembly::default();
        for (i, entry) in file.light.iter().enumerate() {
            let (light, panel) = self.light(i, entry)?;
            if let Some((mesh, material)) = panel {
                let m = materials.len() as u32;
                materials.push(material);
                assembly
                    .add(
                        format!("light[{i}] panel"),
                        &mesh,
                        &Transform::default(),
                        m,
                        false,
                    )
                    .map_err(|reason| {
                        self.error_at(&entry.span(), &format!("light[{i}]"), reason)
                    })?;
            }
            lights.push(light);
        }
        let mut loaded: BTreeMap<&str, u32> = BTreeMap::new();
        let mut placed_meshes = Vec::with_capacity(file.mesh.len());
        for (i, entry) in file.mesh.iter().enumerate() {
            let mesh_entry = entry.get_ref();
            let material = match &mesh_entry.material {
                Some(name) => self.material_named(
                    name.get_ref(),
                    &name.span(),
                    &format!("mesh[{i}].material"),
                    &material_index,
                )?,
                None => {
                    let m = materials.len() as u32;
                    materials.push(Material::default_diffuse());
                    m
                }
            };
            let file_name = mesh_entry.file.get_ref().as_str();
            let id = match loaded.get(file_name) {
                Some(&id) => id,
                None => {
                    let mesh =
                        load_mesh(Path::new(file_name)).map_err(|error| SceneError::Mesh {
                            file: self.file.clone(),
                            line: self.line_of(mesh_entry.file.span().start),
                            key: format!("mesh[{i}].file"),
                            error: Box::new(error),
                        })?;
                    let id = assembly.add_mesh(mesh_entry.name(), mesh);
                    loaded.insert(file_name, id);
                    id
                }
            };
            let key = format!("mesh[{i}]");
            let transform = self.transform(
                &key,
                &mesh_entry.translate,
                &mesh_entry.rotate,
                &mesh_entry.scale,
            )?;
            let smooth = mesh_entry.smooth.unwrap_or(false);
            if mesh_entry.place.unwrap_or(true) {
                assembly
                    .add_instance(id, transform.to_daffine(), material, smooth)
                    .map_err(|reason| self.error_at(&entry.span(), &key, reason))?;
            }
            placed_meshes.push(PlacedMesh {
                id,
                material,
                smooth,
                transform,
            });
        }
        for (i, entry) in file.instance.iter().enumerate() {
            self.place_instances(
                i,
                entry,
                (&file.mesh, &placed_meshes),
                &material_index,
                &mut assembly,
            )?;
        }
        if assembly.triangle_count() == 0 {
            return Err(self.error_at(
                &(0..0),
                "mesh",
                "the scene has no triangles (add a [[mesh]] or an [[instance]])",
            ));
        }
        Ok(assembly.finish(materials, camera, lights, settings))
    }

    fn settings(&self, r: &RenderEntry) -> Result<RenderSettings, SceneError> {
        let mut s = RenderSettings::default();
        let int = |v: &Option<Spanned<i64>>, key: &str, min: i64, max: i64, default: u32| match v {
            None => Ok(default),
            Some(v) if (min..=max).contains(v.get_ref()) => Ok(*v.get_ref() as u32),
            Some(v) => Err(self.error_at(
                &v.span(),
                key,
                format!("{} is out of range: expected {min} to {max}", v.get_ref()),
            )),
        };
        s.width = int(&r.width, "render.width", 1, MAX_SIDE, s.width)?;
        s.height = int(&r.height, "render.height", 1, MAX_SIDE, s.height)?;
        s.spp = int(&r.spp, "render.spp", 1, MAX_SPP, s.spp)?;
        s.max_depth = int(&r.max_depth, "render.max_depth", 0, MAX_DEPTH, s.max_depth)?;
        if let Some(c) = &r.background {
            s.background = self.colour(c, "render.background")?;
        }
        if let Some(c) = &r.ambient {
            s.ambient = self.colour(c, "render.ambient")?;
        }
        Ok(s)
    }

    fn camera(&self, c: &Spanned<CameraEntry>) -> Result<Camera, SceneError> {
        let e = c.get_ref();
        let camera = Camera {
            position: self.point(&e.position, "camera.position")?,
            look_at: self.point(&e.look_at, "camera.look_at")?,
            up: match &e.up {
                Some(u) => self.point(u, "camera.up")?,
                None => Vec3::Y,
            },
            fov_y_degrees: *e.fov.get_ref(),
        };
        match camera.frame_error() {
            Some(reason) => Err(self.error_at(&c.span(), "camera", reason)),
            None => Ok(camera),
        }
    }

    fn material(&self, name: &str, entry: &Spanned<MaterialEntry>) -> Result<Material, SceneError> {
        let e = entry.get_ref();
        let key = |k: &str| format!("materials.{name}.{k}");
        let colour = |v: &Option<V3>, k: &str, default: Vec3| match v {
            Some(c) => self.colour(c, &key(k)),
            None => Ok(default),
        };
        let require = |present: bool, k: &str| {
            if present {
                Ok(())
            } else {
                Err(self.error_at(
                    &entry.span(),
                    &key(k),
                    format!("a {} material needs `{k}`", e.kind.get_ref()),
                ))
            }
        };
        let surface = match e.kind.get_ref().as_str() {
            "diffuse" => Surface::Diffuse {
                albedo: colour(&e.color, "color", Vec3::splat(0.7))?,
            },
            "phong" => {
                require(e.exponent.is_some(), "exponent")?;
                let exponent = e.exponent.as_ref().expect("checked above");
                if !(exponent.get_ref().is_finite() && *exponent.get_ref() >= 0.0) {
                    return Err(self.error_at(
                        &exponent.span(),
                        &key("exponent"),
                        "must be a finite number ≥ 0",
                    ));
                }
                Surface::Phong {
                    albedo: colour(&e.color, "color", Vec3::splat(0.7))?,
                    specular: colour(&e.specular, "specular", Vec3::splat(0.04))?,
                    exponent: *exponent.get_ref(),
                }
            }
            "mirror" => Surface::Mirror {
                reflectance: colour(&e.color, "color", Vec3::splat(0.9))?,
            },
            "glass" => {
                let ior = match &e.ior {
                    Some(ior) if ior.get_ref().is_finite() && *ior.get_ref() > 0.0 => {
                        *ior.get_ref()
                    }
                    Some(ior) => {
                        return Err(self.error_at(
                            &ior.span(),
                            &key("ior"),
                            "must be a finite number > 0",
                        ))
                    }
                    None => 1.5,
                };
                Surface::Glass {
                    ior,
                    tint: colour(&e.color, "color", Vec3::ONE)?,
                }
            }
            other => {
                return Err(self.error_at(
                    &e.kind.span(),
                    &key("type"),
                    format!(
                    "unknown material type {other:?} (expected diffuse, phong, mirror or glass)"
                ),
                ))
            }
        };
        Ok(Material {
            surface,
            emission: colour(&e.emission, "emission", Vec3::ZERO)?,
        })
    }

    /// A light, and for visible area lights the panel the camera sees, with its material.
    fn light(
        &self,
        i: usize,
        entry: &Spanned<LightEntry>,
    ) -> Result<(Light, Option<(TriangleMesh, Material)>), SceneError> {
        let e = entry.get_ref();
        let key = |k: &str| format!("light[{i}].{k}");
        let need = |v: &Option<V3>, k: &str| match v {
            Some(v) => self.point(v, &key(k)),
            None => Err(self.error_at(
                &entry.span(),
                &key(k),
                format!("a {} light needs `{k}`", e.kind.get_ref()),
            )),
        };
        let colour = match &e.color {
            Some(c) => self.colour(c, &key("color"))?,
            None => Vec3::ONE,
        };
        let intensity = match &e.intensity {
            Some(v) if v.get_ref().is_finite() && *v.get_ref() >= 0.0 => *v.get_ref(),
            Some(v) => {
                return Err(self.error_at(
                    &v.span(),
                    &key("intensity"),
                    "must be a finite number ≥ 0",
                ))
            }
            None => 1.0,
        };
        let power = colour * intensity;
        match e.kind.get_ref().as_str() {
            "point" => Ok((
                Light::Point {
                    position: need(&e.position, "position")?,
                    intensity: power,
                },
                None,
            )),
            "directional" => {
                let d = need(&e.direction, "direction")?;
                let direction = d.try_normalize().ok_or_else(|| {
                    self.error_at(&entry.span(), &key("direction"), "must not be zero")
                })?;
                Ok((
                    Light::Directional {
                        direction,
                        irradiance: power,
                    },
                    None,
                ))
            }
            "area" => {
                let corner = need(&e.corner, "corner")?;
                let edge_u = need(&e.edge_u, "edge_u")?;
                let edge_v = need(&e.edge_v, "edge_v")?;
                if edge_u.cross(edge_v).length_squared() <= 0.0 {
                    return Err(self.error_at(
                        &entry.span(),
                        &key("edge_v"),
                        "edge_u and edge_v must span a parallelogram (nonzero, not parallel)",
                    ));
                }
                let samples = match &e.samples {
                    None => 16,
                    Some(s) if (1..=MAX_LIGHT_SAMPLES).contains(s.get_ref()) => *s.get_ref() as u32,
                    Some(s) => {
                        return Err(self.error_at(
                            &s.span(),
                            &key("samples"),
                            format!(
                                "{} is out of range: expected 1 to {MAX_LIGHT_SAMPLES}",
                                s.get_ref()
                            ),
                        ))
                    }
                };
                let panel = e.visible.unwrap_or(true).then(|| {
                    let mesh = TriangleMesh::new(
                        vec![
                            corner,
                            corner + edge_u,
                            corner + edge_u + edge_v,
                            corner + edge_v,
                        ],
                        vec![[0, 1, 2], [0, 2, 3]],
                    )
                    .expect("checked finite");
                    let material = Material {
                        surface: Surface::Diffuse { albedo: Vec3::ZERO },
                        emission: power,
                    };
                    (mesh, material)
                });
                Ok((
                    Light::Rect {
                        corner,
                        edge_u,
                        edge_v,
                        radiance: power,
                        samples,
                    },
                    panel,
                ))
            }
            other => Err(self.error_at(
                &e.kind.span(),
                &key("type"),
                format!("unknown light type {other:?} (expected point, directional or area)"),
            )),
        }
    }

    /// The placement `translate`, `rotate`, `scale` of the table `key` (`mesh[2]`, ...).
    pub(super) fn transform(
        &self,
        key: &str,
        translate: &Option<V3>,
        rotate: &Option<V3>,
        scale: &Option<Spanned<Scale>>,
    ) -> Result<Transform, SceneError> {
        let mut t = Transform::default();
        if let Some(v) = translate {
            t.translate = self.point(v, &format!("{key}.translate"))?;
        }
        if let Some(v) = rotate {
            t.rotate_degrees = self.point(v, &format!("{key}.rotate"))?;
        }
        if let Some(s) = scale {
            let scale = match s.get_ref() {
                Scale::Uniform(k) => Vec3::splat(*k),
                Scale::PerAxis(v) => Vec3::from(v.0),
            };
            if !(scale.is_finite()
                && scale.min_element().abs() > 0.0
                && scale.x * scale.y * scale.z != 0.0)
            {
                return Err(self.error_at(
                    &s.span(),
                    &format!("{key}.scale"),
                    "must be finite and nonzero",
                ));
            }
            t.scale = scale;
        }
        Ok(t)
    }

    /// The index of material `name`, or an error at `span` listing the scene's materials.
    pub(super) fn material_named(
        &self,
        name: &str,
        span: &Range<usize>,
        key: &str,
        material_index: &BTreeMap<String, u32>,
    ) -> Result<u32, SceneError> {
        material_index.get(name).copied().ok_or_else(|| {
            let known: Vec<&str> = material_index.keys().map(String::as_str).collect();
            self.error_at(
                span,
                key,
                format!(
                    "no material named {name:?} (the scene defines: {})",
                    if known.is_empty() {
                        "none".into()
                    } else {
                        known.join(", ")
                    }
                ),
            )
        })
    }

    pub(super) fn point(&self, v: &V3, key: &str) -> Result<Vec3, SceneError> {
        let p = Vec3::from(v.get_ref().0);
        if p.is_finite() {
            Ok(p)
        } else {
            Err(self.error_at(&v.span(), key, "coordinates must be finite"))
        }
    }

    fn colour(&self, v: &V3, key: &str) -> Result<Vec3, SceneError> {
        let c = Vec3::from(v.get_ref().0);
        if c.is_finite() && c.min_element() >= 0.0 {
            Ok(c)
        } else {
            Err(self.error_at(&v.span(), key, "colour components must be finite and ≥ 0"))
        }
    }
}
