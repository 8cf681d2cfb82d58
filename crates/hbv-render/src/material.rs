//! Surface materials: what a surface does with light arriving at it.

use std::f32::consts::PI;

use glam::Vec3;

use crate::optics::reflect;

/// How a surface scatters light, plus what it emits. Colours are linear RGB in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub surface: Surface,
    /// Radiance emitted towards every direction (e.g. the visible panel of an area light).
    pub emission: Vec3,
}

/// The scattering models of a Whitted ray tracer (Whitted 1980, "An improved illumination model
/// for shaded display"): lit by shadow rays (diffuse, Phong), or continued by one reflected and
/// one transmitted ray (mirror, glass).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Lambertian: BRDF `albedo / π`.
    Diffuse { albedo: Vec3 },
    /// Lambertian plus the normalized modified Phong lobe (Lafortune & Willems 1994):
    /// `f = albedo/π + specular · (n+2)/(2π) · max(0, r·wo)^n`, `r` the mirror direction of `wi`.
    Phong {
        albedo: Vec3,
        specular: Vec3,
        exponent: f32,
    },
    /// A perfect mirror reflecting `reflectance` of the light.
    Mirror { reflectance: Vec3 },
    /// A smooth dielectric of index of refraction `ior` (outside: 1): Fresnel-weighted reflection
    /// and refraction; transmitted light is multiplied by `tint`.
    Glass { ior: f32, tint: Vec3 },
}

impl Material {
    /// A non-emitting material.
    pub fn new(surface: Surface) -> Self {
        Material {
            surface,
            emission: Vec3::ZERO,
        }
    }

    /// Grey diffuse: the material of meshes that name none.
    pub fn default_diffuse() -> Self {
        Material::new(Surface::Diffuse {
            albedo: Vec3::splat(0.7),
        })
    }

    /// The BRDF `f(wo, wi)` of the shadow-ray-lit surfaces (zero for mirror and glass, which only
    /// see lights through their reflected and transmitted rays). `n` is the shading normal on the
    /// side of `wo`; `wo` and `wi` point away from the surface.
    pub fn brdf(&self, wo: Vec3, wi: Vec3, n: Vec3) -> Vec3 {
        match self.surface {
            Surface::Diffuse { albedo } => albedo / PI,
            Surface::Phong {
                albedo,
                specular,
                exponent,
            } => {
                let cos_r = reflect(wi, n).dot(wo).max(0.0);
                albedo / PI + specular * ((exponent + 2.0) / (2.0 * PI) * cos_r.powf(exponent))
            }
            Surface::Mirror { .. } | Surface::Glass { .. } => Vec3::ZERO,
        }
    }

    /// Whether shadow rays light this surface.
    pub fn is_lit_by_shadow_rays(&self) -> bool {
        matches!(
            self.surface,
            Surface::Diffuse { .. } | Surface::Phong { .. }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phong_lobe_peaks_at_the_mirror_direction() {
        let m = Material::new(Surface::Phong {
            albedo: Vec3::ZERO,
            specular: Vec3::ONE,
            exponent: 20.0,
        });
        let wi = Vec3::new(1.0, 0.0, 1.0).normalize();
        let mirror = Vec3::new(-1.0, 0.0, 1.0).normalize();
        let peak = m.brdf(mirror, wi, Vec3::Z).x;
        assert!((peak - 22.0 / (2.0 * PI)).abs() < 1e-4);
        assert!(m.brdf(Vec3::Z, wi, Vec3::Z).x < peak);
    }
}
