//! The ray sets `hbv bench` traces, made deterministically from a mesh and a seed.
//!
//! | set | rays | query |
//! | --- | --- | --- |
//! | [`RaySet::Primary`] | pinhole camera outside the box, aimed at its centre; coherent | closest hit |
//! | [`RaySet::Diffuse`] | from random surface points, cosine-distributed; incoherent | closest, any hit |
//! | [`RaySet::Shadow`] | from random surface points to one point light | any hit |
//!
//! Everything is placed relative to the mesh's bounding box ([`Stage`]), so a set means the same
//! on a 36-triangle box and on a million-triangle scan at any scale.

use std::f32::consts::TAU;

use glam::Vec3;
use hbv::geometry::{Aabb, Ray};
use hbv::TriangleMesh;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Vertical field of view of the camera of [`RaySet::Primary`], in degrees.
pub const CAMERA_FOV_DEGREES: f32 = 45.0;

/// Offset of ray starts from the surface they leave, relative to the box diagonal: far enough
/// that a ray cannot hit its own triangle through rounding, near enough to miss no real
/// neighbour.
pub const SURFACE_OFFSET: f32 = 1e-4;

/// End of a shadow ray's interval, just short of the light (`t = 1` is the light itself).
pub const SHADOW_TMAX: f32 = 1.0 - 1e-4;

/// One of the three ray sets of `hbv bench`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RaySet {
    /// Camera rays, unit directions, `[0, +inf]`.
    Primary,
    /// Bounce rays from the surface, unit directions, `[offset, +inf]`.
    Diffuse,
    /// Segments from the surface to the light: direction `light - origin` (not normalized),
    /// `[offset / |d|, 1 - 1e-4]`.
    Shadow,
}

impl RaySet {
    /// All sets, in the order `hbv bench` reports them.
    pub const ALL: [RaySet; 3] = [RaySet::Primary, RaySet::Diffuse, RaySet::Shadow];

    /// The set's name: also the stem of its file, `NAME.npz`.
    pub fn name(self) -> &'static str {
        match self {
            RaySet::Primary => "primary",
            RaySet::Diffuse => "diffuse",
            RaySet::Shadow => "shadow",
        }
    }

    /// `count` rays of this set on `mesh`. The camera set takes no randomness; the surface sets
    /// draw from `seed` (the same seed gives the same rays, and the two surface sets draw
    /// independent points). A mesh without area gives no surface rays.
    pub fn generate(self, mesh: &TriangleMesh, count: usize, seed: u64) -> Vec<Ray> {
        let stage = Stage::new(&mesh.bounds());
        match self {
            RaySet::Primary => {
                let (width, height) = camera_image_size(count);
                let mut rays = primary_rays(&stage, width, height);
                rays.truncate(count);
                rays
            }
            RaySet::Diffuse => diffuse_rays(mesh, &stage, count, seed),
            RaySet::Shadow => shadow_rays(mesh, &stage, count, seed),
        }
    }
}

/// Where the camera and the light stand, derived from a mesh's bounding box alone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stage {
    /// Centre of the box: what the camera looks at.
    pub center: Vec3,
    /// Length of the box diagonal: the unit of every distance here.
    pub diagonal: f32,
    /// The camera's position, `center + (1, 0.6, 0.8) · diagonal`: outside the box on every axis,
    /// 1.41 diagonals away, where the box's bounding sphere fills about 41° of the 45° view.
    pub eye: Vec3,
    /// The point light, `center + (0.3, 1, 0.9) · diagonal`: outside the box and above it whether
    /// the mesh's up axis is y (scans) or z (the built-in scene).
    pub light: Vec3,
    /// How far rays leaving the surface start from it: [`SURFACE_OFFSET`] × diagonal.
    pub offset: f32,
}

impl Stage {
    pub fn new(bounds: &Aabb) -> Self {
        let (center, diagonal) = if bounds.is_empty() {
            (Vec3::ZERO, 0.0)
        } else {
            (bounds.center(), bounds.extent().length())
        };
        Self {
            center,
            diagonal,
            eye: center + Vec3::new(1.0, 0.6, 0.8) * diagonal,
            light: center + Vec3::new(0.3, 1.0, 0.9) * diagonal,
            offset: SURFACE_OFFSET * diagonal,
        }
    }
}

/// The camera image for `count` rays: the squarest `width × height` with at least `count`
/// pixels (`width = ⌈√count⌉`), of which the set takes the first `count` in scanline order.
pub fn camera_image_size(count: usize) -> (u32, u32) {
    if count == 0 {
        return (0, 0);
    }
    let width = (count as f64).sqrt().ceil() as usize;
    let height = count.div_ceil(width);
    (width as u32, height as u32)
}

/// One ray through the centre of each pixel of a `width × height` pinhole camera at `stage.eye`
/// looking at `stage.center` (y up in the image, [`CAMERA_FOV_DEGREES`] vertically), in scanline
/// order from the top left. Unit directions, interval `[0, +inf]`.
pub fn primary_rays(stage: &Stage, width: u32, height: u32) -> Vec<Ray> {
    let forward = (stage.center - stage.eye).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
    let up = right.cross(forward);
    let half_height = (CAMERA_FOV_DEGREES.to_radians() / 2.0).tan();
    let half_width = half_height * width as f32 / height.max(1) as f32;
    let mut rays = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * half_height;
        for x in 0..width {
            let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * half_width;
            let direction = (forward + sx * right + sy * up).normalize();
            rays.push(Ray::new(stage.eye, direction));
        }
    }
    rays
}

/// `count` diffuse bounce rays: each from a random surface point (triangle chosen by area,
/// uniform over it) in a cosine-distributed direction about the triangle's geometric normal,
/// flipped to either side at random (a two-sided surface). Interval `[stage.offset, +inf]`.
pub fn diffuse_rays(mesh: &TriangleMesh, stage: &Stage, count: usize, seed: u64) -> Vec<Ray> {
    let Some(surface) = SurfaceSampler::new(mesh) else {
        return Vec::new();
    };
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ DIFFUSE_STREAM);
    (0..count)
        .map(|_| {
            let (point, normal) = surface.sample(&mut rng);
            let normal = if rng.random::<bool>() {
                normal
            } else {
                -normal
            };
            let direction = cosine_direction(normal, rng.random(), rng.random());
            Ray::new(point, direction).with_interval(stage.offset, f32::INFINITY)
        })
        .collect()
}

/// `count` shadow rays: each from a random surface point (as in [`diffuse_rays`]) to
/// `stage.light`. The direction is `light - point`, not normalized, so the segment
/// `[offset / |d|, 1 - 1e-4]` starts `stage.offset` from the surface and ends just before the
/// light; any hit on it is a shadow.
pub fn shadow_rays(mesh: &TriangleMesh, stage: &Stage, count: usize, seed: u64) -> Vec<Ray> {
    let Some(surface) = SurfaceSampler::new(mesh) else {
        return Vec::new();
    };
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ SHADOW_STREAM);
    (0..count)
        .map(|_| {
            let (point, _) = surface.sample(&mut rng);
            let direction = stage.light - point;
            // tmin is in units of |d|: divide, so that the offset is a distance again.
            let tmin = stage.offset / direction.length().max(f32::MIN_POSITIVE);
            Ray::new(point, direction).with_interval(tmin.min(SHADOW_TMAX), SHADOW_TMAX)
        })
        .collect()
}

/// Seeds of the two surface sets are the user's seed mixed with these, so that diffuse and shadow
/// rays leave from independent points.
const DIFFUSE_STREAM: u64 = 0xd1ff_05e0_0000_0001;
const SHADOW_STREAM: u64 = 0x05ad_0000_0000_0002;

/// Uniform random points on a mesh's surface: a triangle by area (a binary search in the
/// cumulative areas), then a point uniform over it.
struct SurfaceSampler<'a> {
    mesh: &'a TriangleMesh,
    /// Triangles of non-zero area, in face order.
    triangles: Vec<u32>,
    /// `cumulative[i]`: total area of `triangles[..=i]` (twice the area, in f64: only ratios
    /// matter).
    cumulative: Vec<f64>,
}

impl<'a> SurfaceSampler<'a> {
    /// `None` when the mesh has no area to sample.
    fn new(mesh: &'a TriangleMesh) -> Option<Self> {
        let mut triangles = Vec::new();
        let mut cumulative = Vec::new();
        let mut total = 0.0;
        for (i, t) in mesh.triangles().enumerate() {
            let area = t.scaled_normal().length();
            if area > 0.0 {
                total += area;
                triangles.push(i as u32);
                cumulative.push(total);
            }
        }
        (total > 0.0).then_some(Self {
            mesh,
            triangles,
            cumulative,
        })
    }

    /// A point uniform on the surface and the unit geometric normal of its triangle,
    /// `(p1 - p0) × (p2 - p0)` normalized.
    fn sample(&self, rng: &mut Pcg64Mcg) -> (Vec3, Vec3) {
        let total = *self.cumulative.last().expect("a sampler has area");
        let x = rng.random::<f64>() * total;
        let k = self
            .cumulative
            .partition_point(|&c| c <= x)
            .min(self.triangles.len() - 1);
        let t = self.mesh.triangle(self.triangles[k] as usize);
        // Uniform barycentrics by the square-root warp (Osada et al. 2002, "Shape distributions"):
        // P = (1 - √r1) p0 + √r1 (1 - r2) p1 + √r1 r2 p2.
        let (r1, r2): (f32, f32) = (rng.random(), rng.random());
        let s = r1.sqrt();
        let point = (1.0 - s) * t.p0 + s * (1.0 - r2) * t.p1 + s * r2 * t.p2;
        (point, t.scaled_normal().normalize().as_vec3())
    }
}

/// A direction about the unit `normal` with density `cos θ / π` (Malley's method: a uniform
/// point on the unit disc, `(√r1 cos 2πr2, √r1 sin 2πr2)`, lifted to the hemisphere), in the
/// orthonormal frame of Duff et al. 2017 ("Building an orthonormal basis, revisited").
fn cosine_direction(normal: Vec3, r1: f32, r2: f32) -> Vec3 {
    let (tangent, bitangent) = normal.any_orthonormal_pair();
    let radius = r1.sqrt();
    let phi = TAU * r2;
    let z = (1.0 - r1).max(0.0).sqrt();
    (radius * phi.cos()) * tangent + (radius * phi.sin()) * bitangent + z * normal
}

/// Rays a Whitted-style renderer spawns at the hits of its camera rays, each set in the order
/// of the primary rays that made it (camera rays that miss spawn nothing): the order that gives
/// caches their coherence.
#[derive(Clone, Debug, Default)]
pub struct SecondaryRays {
    /// Mirror reflections `d − 2 (d·n) n` off the hit triangle; unit directions,
    /// `[offset, +inf]`.
    pub reflection: Vec<Ray>,
    /// Cosine-distributed bounces about the normal facing the incoming ray; `[offset, +inf]`.
    pub diffuse: Vec<Ray>,
    /// Segments from the hit point to `stage.light`, as in [`shadow_rays`].
    pub shadow: Vec<Ray>,
}

/// The secondary rays of `primary` given its closest `hits` (one per ray, same order). The hit
/// point is taken from the barycentrics on the triangle (more accurate than `o + t d`); the
/// diffuse directions draw from `seed`.
pub fn secondary_rays(
    mesh: &TriangleMesh,
    stage: &Stage,
    primary: &[Ray],
    hits: &[Option<hbv::Hit>],
    seed: u64,
) -> SecondaryRays {
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ BOUNCE_STREAM);
    let mut out = SecondaryRays::default();
    for (ray, hit) in primary.iter().zip(hits) {
        let Some(hit) = hit else { continue };
        let t = mesh.triangle(hit.prim as usize);
        let point = (1.0 - hit.u - hit.v) * t.p0 + hit.u * t.p1 + hit.v * t.p2;
        let mut normal = t.scaled_normal().normalize().as_vec3();
        if normal.dot(ray.direction) > 0.0 {
            normal = -normal;
        }
        let d = ray.direction.normalize();
        let reflected = d - 2.0 * d.dot(normal) * normal;
        out.reflection
            .push(Ray::new(point, reflected).with_interval(stage.offset, f32::INFINITY));
        let bounce = cosine_direction(normal, rng.random(), rng.random());
        out.diffuse
            .push(Ray::new(point, bounce).with_interval(stage.offset, f32::INFINITY));
        let to_light = stage.light - point;
        let tmin = stage.offset / to_light.length().max(f32::MIN_POSITIVE);
        out.shadow
            .push(Ray::new(point, to_light).with_interval(tmin.min(SHADOW_TMAX), SHADOW_TMAX));
    }
    out
}

/// Seed mix of the bounce directions of [`secondary_rays`].
const BOUNCE_STREAM: u64 = 0xb0b0_0000_0000_0003;

#[cfg(test)]
mod tests {
    use super::*;
    use hbv::mesh::procedural::{ground_plane, icosphere};

    #[test]
    fn camera_image_is_the_squarest_that_holds_the_count() {
        assert_eq!(camera_image_size(0), (0, 0));
        assert_eq!(camera_image_size(1), (1, 1));
        assert_eq!(camera_image_size(262_144), (512, 512));
        assert_eq!(camera_image_size(2000), (45, 45));
        let mesh = icosphere(Vec3::ZERO, 1.0, 1);
        assert_eq!(RaySet::Primary.generate(&mesh, 2000, 0).len(), 2000);
    }

    #[test]
    fn the_camera_looks_at_the_centre_from_outside_the_box() {
        let mesh = icosphere(Vec3::new(3.0, -1.0, 2.0), 2.0, 2);
        let bounds = mesh.bounds();
        let stage = Stage::new(&bounds);
        assert!(!bounds.contains(&Aabb::new(stage.eye, stage.eye)));
        assert!(!bounds.contains(&Aabb::new(stage.light, stage.light)));
        // The centre pixel of an odd image looks straight at the centre.
        let rays = primary_rays(&stage, 5, 5);
        let centre = rays[12];
        let to_centre = (stage.center - stage.eye).normalize();
        assert!(centre.direction.dot(to_centre) > 1.0 - 1e-6);
        assert!(rays
            .iter()
            .all(|r| (r.direction.length() - 1.0).abs() < 1e-5));
    }

    #[test]
    fn surface_origins_lie_on_the_mesh_and_avoid_zero_area() {
        // A flat plane at z = 0.5: every origin is on it, every diffuse direction leaves it.
        let plane = ground_plane(1.0, 0.5, 3);
        let mut positions = plane.positions().to_vec();
        let mut indices = plane.indices().to_vec();
        // A degenerate triangle far away must never be drawn.
        positions.extend([Vec3::splat(50.0), Vec3::splat(50.0), Vec3::splat(51.0)]);
        let n = positions.len() as u32;
        indices.push([n - 3, n - 2, n - 1]);
        let mesh = TriangleMesh::new(positions, indices).unwrap();
        let stage = Stage::new(&mesh.bounds());
        for ray in diffuse_rays(&mesh, &stage, 2000, 7) {
            assert!((ray.origin.z - 0.5).abs() < 1e-6, "{ray:?}");
            assert!(ray.origin.x.abs() <= 1.0 && ray.origin.y.abs() <= 1.0);
            assert_eq!(ray.tmin, stage.offset);
        }
    }

    #[test]
    fn diffuse_directions_are_cosine_distributed() {
        // E[cos θ] = ∫ cos θ · cos θ / π dω = 2/3, on either side of the surface.
        let mesh = icosphere(Vec3::ZERO, 1.0, 2);
        let stage = Stage::new(&mesh.bounds());
        let rays = diffuse_rays(&mesh, &stage, 20_000, 3);
        let mut sum = 0.0;
        let mut outward = 0;
        for r in &rays {
            // On a sphere at the origin the normal is about the position's direction.
            let cos = r.direction.dot(r.origin.normalize());
            outward += (cos > 0.0) as usize;
            sum += cos.abs() as f64;
        }
        let mean = sum / rays.len() as f64;
        assert!((mean - 2.0 / 3.0).abs() < 0.01, "mean cos θ = {mean}");
        assert!((outward as f64 / rays.len() as f64 - 0.5).abs() < 0.02);
    }

    #[test]
    fn secondary_rays_leave_hits_in_primary_order() {
        let mesh = icosphere(Vec3::ZERO, 1.0, 3);
        let stage = Stage::new(&mesh.bounds());
        let primary = primary_rays(&stage, 16, 16);
        let hits: Vec<_> = primary
            .iter()
            .map(|r| hbv::Accelerator::intersect(&hbv::BruteForce::new(&mesh), r))
            .collect();
        let s = secondary_rays(&mesh, &stage, &primary, &hits, 1);
        let n = hits.iter().flatten().count();
        assert!(n > 0 && s.reflection.len() == n && s.diffuse.len() == n && s.shadow.len() == n);
        for (r, d) in s.reflection.iter().zip(&s.diffuse) {
            // On a sphere seen from outside, reflections and bounces leave outwards.
            assert!((r.origin.length() - 1.0).abs() < 0.02);
            assert!(r.direction.dot(r.origin) > 0.0 && d.direction.dot(d.origin) > 0.0);
        }
    }

    #[test]
    fn a_mesh_without_area_gives_no_surface_rays() {
        let mesh =
            TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]).unwrap();
        assert!(RaySet::Diffuse.generate(&mesh, 10, 0).is_empty());
        assert!(RaySet::Shadow.generate(&mesh, 10, 0).is_empty());
    }
}
