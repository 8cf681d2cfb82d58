//! Whitted's recursive ray tracing (Whitted 1980, "An improved illumination model for shaded
//! display"): at each hit, direct light through shadow rays, plus one mirror-reflected and one
//! refracted ray weighted by the Fresnel equations, to a maximum depth.
//!
//! `L(x, wo) = Le + ambient·albedo + Σ_lights Σ_k f(wo, wi_k) E_k cos θ_k V(x, y_k)`
//! `        + F · L(x, reflect(wo)) + (1 − F) · tint · L(x, refract(wo))`

use glam::Vec3;
use hbv::geometry::Ray;

use crate::material::Surface;
use crate::optics::{fresnel_dielectric, reflect, refract};
use crate::ray_kind::RayKind;
use crate::sampler::PixelSampler;
use crate::scene::{Scene, SurfacePoint};
use crate::tracer::{RayTally, SceneTracer};

/// What the primary ray of a sample saw, for the depth, normal and primitive-id passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimaryHit {
    /// Distance along the (unit) primary ray.
    pub depth: f32,
    /// Shading normal, turned towards the camera.
    pub normal: Vec3,
    /// The face's id in the flattened scene's numbering ([`SurfacePoint::face`]).
    pub face: u64,
}

/// The Whitted integrator of one scene, tracing through one [`SceneTracer`].
pub struct Whitted<'a> {
    scene: &'a Scene,
    tracer: &'a SceneTracer,
    /// Offset of secondary ray origins along the geometric normal, relative to the size of the
    /// hit point's coordinates: far above the watertight test's error (a few ulps), far below
    /// any feature of a scene.
    relative_offset: f32,
}

impl<'a> Whitted<'a> {
    pub fn new(scene: &'a Scene, tracer: &'a SceneTracer) -> Self {
        Whitted {
            scene,
            tracer,
            relative_offset: 1e-4,
        }
    }

    /// Radiance along a primary ray, and what it hit.
    pub fn primary(
        &self,
        ray: &Ray,
        sampler: &mut PixelSampler,
        tally: &mut RayTally,
    ) -> (Vec3, Option<PrimaryHit>) {
        match self.tracer.intersect(ray, RayKind::Primary, tally) {
            None => (self.scene.settings.background, None),
            Some(hit) => {
                let point = self.scene.surface(ray, &hit);
                let seen = PrimaryHit {
                    depth: hit.t,
                    normal: point.shading,
                    face: point.face,
                };
                (self.shade(ray, &point, 0, sampler, tally), Some(seen))
            }
        }
    }

    /// Radiance along a reflected or transmitted ray at recursion `depth`.
    fn trace(
        &self,
        ray: &Ray,
        kind: RayKind,
        depth: u32,
        sampler: &mut PixelSampler,
        tally: &mut RayTally,
    ) -> Vec3 {
        match self.tracer.intersect(ray, kind, tally) {
            None => self.scene.settings.background,
            Some(hit) => {
                let point = self.scene.surface(ray, &hit);
                self.shade(ray, &point, depth, sampler, tally)
            }
        }
    }

    /// The origin of a ray leaving `point` on the side of `towards · geometric`.
    fn offset_origin(&self, point: &SurfacePoint, outwards: bool) -> Vec3 {
        let eps = self.relative_offset * point.position.abs().max_element().max(1.0);
        let n = if outwards {
            point.geometric
        } else {
            -point.geometric
        };
        point.position + eps * n
    }

    fn shade(
        &self,
        ray: &Ray,
        point: &SurfacePoint,
        depth: u32,
        sampler: &mut PixelSampler,
        tally: &mut RayTally,
    ) -> Vec3 {
        let material = self.scene.material_of(point.instance);
        let wo = -ray.direction;
        let settings = &self.scene.settings;
        let mut radiance = if point.front {
            material.emission
        } else {
            Vec3::ZERO
        };
        match material.surface {
            Surface::Diffuse { albedo } | Surface::Phong { albedo, .. } => {
                radiance += settings.ambient * albedo;
                radiance += self.direct_light(wo, point, material, sampler, tally);
            }
            Surface::Mirror { reflectance } => {
                if depth < settings.max_depth {
                    let r = Ray::new(self.offset_origin(point, true), reflect(wo, point.shading));
                    radiance +=
                        reflectance * self.trace(&r, RayKind::Reflected, depth + 1, sampler, tally);
                }
            }
            Surface::Glass { ior, tint } => {
                if depth < settings.max_depth {
                    let eta = if point.front { ior } else { 1.0 / ior };
                    let fresnel = fresnel_dielectric(wo.dot(point.shading), eta);
                    let r = Ray::new(self.offset_origin(point, true), reflect(wo, point.shading));
                    radiance +=
                        fresnel * self.trace(&r, RayKind::Reflected, depth + 1, sampler, tally);
                    if fresnel < 1.0 {
                        if let Some(wt) = refract(wo, point.shading, eta) {
                            let t = Ray::new(self.offset_origin(point, false), wt);
                            radiance += (1.0 - fresnel)
                                * tint
                                * self.trace(&t, RayKind::Transmitted, depth + 1, sampler, tally);
                        }
                    }
                }
            }
        }
        radiance
    }

    /// `Σ_lights Σ_k f(wo, wi) E cos θ V`: one shadow ray per light sample.
    fn direct_light(
        &self,
        wo: Vec3,
        point: &SurfacePoint,
        material: &crate::material::Material,
        sampler: &mut PixelSampler,
        tally: &mut RayTally,
    ) -> Vec3 {
        let mut sum = Vec3::ZERO;
        if material.surface == (Surface::Diffuse { albedo: Vec3::ZERO }) {
            return sum; // black (a light's panel): no shadow ray can change it
        }
        let origin = self.offset_origin(point, true);
        for (index, light) in self.scene.lights.iter().enumerate() {
            for k in 0..light.sample_count() {
                let Some(sample) = light.sample(point.position, k, sampler) else {
                    continue;
                };
                let cos = point.shading.dot(sample.direction);
                if cos <= 0.0 || point.geometric.dot(sample.direction) <= 0.0 {
                    continue;
                }
                // Stop just short of the light, so that its own panel does not block it.
                let shadow = Ray::new(origin, sample.direction)
                    .with_interval(0.0, sample.distance * (1.0 - 1e-4));
                if !self.tracer.occluded(&shadow, index as u32, k, tally) {
                    sum += material.brdf(wo, sample.direction, point.shading)
                        * sample.irradiance
                        * cos;
                }
            }
        }
        sum
    }
}
