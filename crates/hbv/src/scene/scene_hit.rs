//! `SceneRay` (a ray with its mask) and `SceneHit` (a hit with its instance and normal).

use glam::{DVec3, Vec3};

use crate::geometry::Ray;
use crate::query::Hit;

/// A world-space ray and the instances it sees: instance `i` is seen only if
/// `mask & mask_i != 0` (a lidar that ignores its own vehicle gives the vehicle a bit its rays
/// leave out).
///
/// A ray made by [`SceneRay::from_f64`] keeps its origin to about `2^-48 |o|` (float32 alone
/// holds `2^-24 |o|`: decimetres at UTM coordinates): `ray.origin` is its float32 value, used to
/// walk the top level, and the rest is kept beside it for carrying the ray into each instance's
/// space ([`SceneRay::origin`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneRay {
    pub ray: Ray,
    pub mask: u32,
    /// `o - ray.origin` rounded to f32, for an origin `o` given in f64; zero otherwise.
    origin_rest: Vec3,
}

impl SceneRay {
    /// Every bit set: the ray sees every instance whose own mask is not zero.
    pub const ALL: u32 = u32::MAX;

    /// A ray that sees every instance (mask [`SceneRay::ALL`]).
    pub fn new(ray: Ray) -> Self {
        Self {
            ray,
            mask: Self::ALL,
            origin_rest: Vec3::ZERO,
        }
    }

    /// A ray from `origin` along `direction` over `[0, +inf]` that sees every instance, its
    /// origin kept to about `2^-48 |origin|` (type notes). The direction is rounded to f32 (a
    /// relative error, as harmless far from the origin as near it).
    pub fn from_f64(origin: DVec3, direction: DVec3) -> Self {
        let rounded = origin.as_vec3();
        Self {
            origin_rest: (origin - rounded.as_dvec3()).as_vec3(),
            ..Self::new(Ray::new(rounded, direction.as_vec3()))
        }
    }

    /// The origin as precisely as it is known: `ray.origin` plus the rest an f64 origin had.
    #[inline]
    pub fn origin(&self) -> DVec3 {
        self.ray.origin.as_dvec3() + self.origin_rest.as_dvec3()
    }

    /// The same ray over `[tmin, tmax]`.
    pub fn with_interval(self, tmin: f32, tmax: f32) -> Self {
        Self {
            ray: self.ray.with_interval(tmin, tmax),
            ..self
        }
    }

    /// The same ray with mask `mask`.
    pub fn with_mask(self, mask: u32) -> Self {
        Self { mask, ..self }
    }

    /// Whether the ray sees an instance whose mask is `instance_mask`.
    #[inline]
    pub fn sees(&self, instance_mask: u32) -> bool {
        self.mask & instance_mask != 0
    }
}

impl From<Ray> for SceneRay {
    fn from(ray: Ray) -> Self {
        Self::new(ray)
    }
}

/// The closest hit of a ray in a scene.
///
/// `prim`, `u`, `v` are those of the instance's mesh (`prim` indexes its triangles, `u`, `v` are
/// barycentrics of that triangle: the hit is `(1-u-v) p0 + u p1 + v p2` of its vertices in file
/// order); `t` is the parameter of the world-space ray, `ray.at(t)`. `normal` is the unit
/// geometric normal in world space, `normalize(cross(p1 - p0, p2 - p0))` of the triangle's
/// world-space vertices (a mirroring transform flips it; it does not face the ray).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub prim: u32,
    /// The instance's id (the number [`Scene::add_instance`](super::Scene::add_instance) gave).
    pub instance: u32,
    pub normal: Vec3,
}

impl SceneHit {
    /// Whether a hit at `t` on `(instance, prim)` should replace `best`: nearer, or as near on a
    /// smaller instance, or on the same instance with a smaller `prim`. The order is that of the
    /// flattened scene's face ids (`offset[instance] + prim`), so that the scene and a brute
    /// force over its flattened triangles break ties alike, whatever the traversal order.
    #[inline]
    pub fn is_closer(t: f32, instance: u32, prim: u32, best: &Option<SceneHit>) -> bool {
        match best {
            None => true,
            Some(b) => t < b.t || (t == b.t && (instance, prim) < (b.instance, b.prim)),
        }
    }

    /// Puts the mesh hit `hit` on `instance` into `best` when it [`is_closer`](Self::is_closer),
    /// and says whether it did. Its normal is left zero: it is computed once, for the final hit.
    #[inline]
    pub(crate) fn keep_closer(best: &mut Option<SceneHit>, instance: u32, hit: &Hit) -> bool {
        let closer = Self::is_closer(hit.t, instance, hit.prim, best);
        if closer {
            *best = Some(SceneHit {
                t: hit.t,
                u: hit.u,
                v: hit.v,
                prim: hit.prim,
                instance,
                normal: Vec3::ZERO,
            });
        }
        closer
    }
}
