//! `[[instance]]` tables: a mesh of the scene placed again, once or as a grid of copies with
//! random turns, sizes and offsets (documented in `docs/SCENES.md`).

use std::collections::BTreeMap;

use glam::{DAffine3, Vec3};
use hbv::scene::InstanceTransform;
use serde::Deserialize;
use toml::Spanned;

use super::file::{Context, MeshEntry, PlacedMesh, Scale, V3};
use super::{SceneAssembly, SceneError, Transform};
use crate::sampler::PixelSampler;

/// Most copies one `[[instance]]` table may make: far beyond any sensible scene, small enough
/// that a typo (`grid = [100000, 1, 100000]`) is refused before it fills the memory.
const MAX_COPIES: u64 = 1 << 24;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct InstanceEntry {
    mesh: Spanned<String>,
    material: Option<Spanned<MaterialNames>>,
    smooth: Option<bool>,
    translate: Option<V3>,
    rotate: Option<V3>,
    scale: Option<Spanned<Scale>>,
    matrix: Option<Spanned<Vec<Vec<f64>>>>,
    grid: Option<Spanned<Vec<i64>>>,
    spacing: Option<V3>,
    random_rotate: Option<V3>,
    random_scale: Option<Spanned<Vec<f32>>>,
    random_offset: Option<V3>,
    seed: Option<Spanned<i64>>,
}

/// `material = "name"`, or `material = ["a", "b", ...]`: each copy takes one at random.
#[derive(Deserialize)]
#[serde(untagged)]
enum MaterialNames {
    One(String),
    Many(Vec<String>),
}

/// How each copy of a grid varies, drawn per copy.
struct Variation {
    spacing: Vec3,
    /// Each angle grows by a uniform amount in `[0, r)`.
    rotate: Vec3,
    /// The scale is multiplied by a uniform factor in `[lo, hi]`.
    scale: (f32, f32),
    /// Each coordinate moves by a uniform amount in `[-r, r]`.
    offset: Vec3,
}

impl Context<'_> {
    /// Adds the instances of `[[instance]]` table `i`: `grid` copies (one by default) of the
    /// mesh it names, each placed by its own transform after the `[[mesh]]`'s own placement.
    pub(super) fn place_instances(
        &self,
        i: usize,
        entry: &Spanned<InstanceEntry>,
        (mesh_entries, placed): (&[Spanned<MeshEntry>], &[PlacedMesh]),
        material_index: &BTreeMap<String, u32>,
        assembly: &mut SceneAssembly,
    ) -> Result<(), SceneError> {
        let e = entry.get_ref();
        let key = |k: &str| format!("instance[{i}].{k}");
        let mesh = self.mesh_named(&e.mesh, &key("mesh"), mesh_entries, placed)?;
        let materials = match &e.material {
            None => vec![mesh.material],
            Some(names) => {
                let list = match names.get_ref() {
                    MaterialNames::One(name) => std::slice::from_ref(name),
                    MaterialNames::Many(list) => list.as_slice(),
                };
                if list.is_empty() {
                    return Err(self.error_at(
                        &names.span(),
                        &key("material"),
                        "the list names no material",
                    ));
                }
                list.iter()
                    .map(|n| {
                        self.material_named(n, &names.span(), &key("material"), material_index)
                    })
                    .collect::<Result<Vec<u32>, _>>()?
            }
        };
        let smooth = e.smooth.unwrap_or(mesh.smooth);
        let grid = self.grid(e, &key("grid"))?;
        let variation = self.variation(e, &key)?;
        let base = match &e.matrix {
            Some(m) => {
                let others = [
                    (e.translate.is_some(), "translate"),
                    (e.rotate.is_some(), "rotate"),
                    (e.scale.is_some(), "scale"),
                    (e.random_rotate.is_some(), "random_rotate"),
                    (e.random_scale.is_some(), "random_scale"),
                ];
                if let Some((_, other)) = others.iter().find(|(given, _)| *given) {
                    return Err(self.error_at(
                        &m.span(),
                        &key("matrix"),
                        format!("give either `matrix` or `{other}`, not both"),
                    ));
                }
                Placement::Matrix(self.matrix(m, &key("matrix"))?.affine())
            }
            None => Placement::Parts(self.transform(
                &format!("instance[{i}]"),
                &e.translate,
                &e.rotate,
                &e.scale,
            )?),
        };
        let seed = e.seed.as_ref().map_or(0, |s| *s.get_ref()) as u64;
        let mut random = PixelSampler::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ i as u64);
        let local = mesh.transform.to_daffine();
        for z in 0..grid[2] {
            for y in 0..grid[1] {
                for x in 0..grid[0] {
                    let cell = Vec3::new(x as f32, y as f32, z as f32);
                    let copy = variation.copy(&base, cell, &mut random);
                    let material = materials[random.next_u32() as usize % materials.len()];
                    assembly
                        .add_instance(mesh.id, copy * local, material, smooth)
                        .map_err(|reason| {
                            let which = if grid == [1, 1, 1] {
                                String::new()
                            } else {
                                format!("copy [{x}, {y}, {z}]: ")
                            };
                            self.error_at(
                                &entry.span(),
                                &format!("instance[{i}]"),
                                format!("{which}{reason}"),
                            )
                        })?;
                }
            }
        }
        Ok(())
    }

    /// The `[[mesh]]` named `name`, or an error naming the scene's meshes (or the tables that
    /// share the name).
    fn mesh_named<'m>(
        &self,
        name: &Spanned<String>,
        key: &str,
        mesh_entries: &[Spanned<MeshEntry>],
        placed: &'m [PlacedMesh],
    ) -> Result<&'m PlacedMesh, SceneError> {
        let matches: Vec<usize> = (0..mesh_entries.len())
            .filter(|&j| mesh_entries[j].get_ref().name() == name.get_ref())
            .collect();
        match matches.as_slice() {
            [j] => Ok(&placed[*j]),
            [] => {
                let known: Vec<String> = mesh_entries
                    .iter()
                    .map(|m| format!("{:?}", m.get_ref().name()))
                    .collect();
                Err(self.error_at(
                    &name.span(),
                    key,
                    format!(
                        "no mesh named {:?} (the scene's [[mesh]] tables name: {})",
                        name.get_ref(),
                        if known.is_empty() {
                            "none".into()
                        } else {
                            known.join(", ")
                        }
                    ),
                ))
            }
            several => Err(self.error_at(
                &name.span(),
                key,
                format!(
                    "{} [[mesh]] tables are named {:?} ({}): give them distinct `name`s",
                    several.len(),
                    name.get_ref(),
                    several
                        .iter()
                        .map(|j| format!("mesh[{j}]"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        }
    }

    /// `grid = [nx, ny, nz]`: each at least 1, at most [`MAX_COPIES`] in all; `[1, 1, 1]` when
    /// absent.
    fn grid(&self, e: &InstanceEntry, key: &str) -> Result<[u64; 3], SceneError> {
        let Some(grid) = &e.grid else {
            return Ok([1, 1, 1]);
        };
        let counts = grid.get_ref();
        let valid = counts.len() == 3 && counts.iter().all(|&n| n >= 1);
        let total = counts
            .iter()
            .try_fold(1u64, |a, &n| a.checked_mul(u64::try_from(n).ok()?));
        match (valid, total) {
            (true, Some(total)) if total <= MAX_COPIES => {
                Ok([counts[0] as u64, counts[1] as u64, counts[2] as u64])
            }
            (true, _) => {
                Err(self.error_at(&grid.span(), key, format!("more than {MAX_COPIES} copies")))
            }
            (false, _) => Err(self.error_at(
                &grid.span(),
                key,
                "must be 3 whole numbers ≥ 1 (copies along x, y and z)",
            )),
        }
    }

    /// The grid's spacing and the random ranges, checked.
    fn variation(
        &self,
        e: &InstanceEntry,
        key: &dyn Fn(&str) -> String,
    ) -> Result<Variation, SceneError> {
        let vector = |v: &Option<V3>, k: &str, nonnegative: bool| -> Result<Vec3, SceneError> {
            let Some(v) = v else { return Ok(Vec3::ZERO) };
            let p = self.point(v, &key(k))?;
            if nonnegative && p.min_element() < 0.0 {
                return Err(self.error_at(&v.span(), &key(k), "must not be negative"));
            }
            Ok(p)
        };
        let scale = match &e.random_scale {
            None => (1.0, 1.0),
            Some(s) => match s.get_ref().as_slice() {
                &[lo, hi] if lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi => (lo, hi),
                _ => {
                    return Err(self.error_at(
                        &s.span(),
                        &key("random_scale"),
                        "must be [smallest, largest] factors, 0 < smallest ≤ largest, finite",
                    ))
                }
            },
        };
        Ok(Variation {
            spacing: vector(&e.spacing, "spacing", false)?,
            rotate: vector(&e.random_rotate, "random_rotate", true)?,
            scale,
            offset: vector(&e.random_offset, "random_offset", true)?,
        })
    }

    /// `matrix = [[a, b, c, x], [d, e, f, y], [g, h, i, z]]`: the rows of `[A | b]`, checked as
    /// an instance's transform (finite, invertible).
    fn matrix(
        &self,
        m: &Spanned<Vec<Vec<f64>>>,
        key: &str,
    ) -> Result<InstanceTransform, SceneError> {
        let rows = m.get_ref();
        if rows.len() != 3 || rows.iter().any(|r| r.len() != 4) {
            return Err(self.error_at(
                &m.span(),
                key,
                "must be 3 rows of 4 numbers: the rows of [A | b] in world = A · local + b",
            ));
        }
        let row = |i: usize| [rows[i][0], rows[i][1], rows[i][2], rows[i][3]];
        InstanceTransform::from_rows([row(0), row(1), row(2)])
            .map_err(|e| self.error_at(&m.span(), key, e.to_string()))
    }
}

/// An `[[instance]]`'s own placement: scale, rotate, translate, or a matrix.
enum Placement {
    Parts(Transform),
    /// `[A | b]`, checked ([`InstanceTransform::new`]).
    Matrix(DAffine3),
}

impl Variation {
    /// The transform of the copy in grid cell `cell`: the placement moved by `spacing ⊙ cell`
    /// and by a random offset; for a placement by parts, also turned and scaled at random.
    /// Draws the same numbers whichever ranges are given, so that adding one range does not
    /// change what the others draw.
    fn copy(&self, base: &Placement, cell: Vec3, random: &mut PixelSampler) -> DAffine3 {
        let mut draw3 = || Vec3::new(random.next_f32(), random.next_f32(), random.next_f32());
        let (turn, offset) = (draw3(), draw3());
        let factor = self.scale.0 + random.next_f32() * (self.scale.1 - self.scale.0);
        let shift = self.spacing * cell + self.offset * (2.0 * offset - Vec3::ONE);
        match base {
            Placement::Parts(t) => Transform {
                translate: t.translate + shift,
                rotate_degrees: t.rotate_degrees + self.rotate * turn,
                scale: t.scale * factor,
            }
            .to_daffine(),
            Placement::Matrix(m) => DAffine3::from_translation(shift.as_dvec3()) * *m,
        }
    }
}
