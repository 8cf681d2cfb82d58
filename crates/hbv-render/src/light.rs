//! Light sources: point, directional, and rectangular area lights sampled with many shadow rays.

use glam::Vec3;

use crate::sampler::PixelSampler;

/// A light of the scene. Colours are linear RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// An isotropic point source of radiant `intensity` (W/sr per channel): irradiance
    /// `E = I cos θ / d²` at distance `d`.
    Point { position: Vec3, intensity: Vec3 },
    /// A source at infinity whose light travels along `direction` (unit), giving `irradiance`
    /// on a surface facing it: `E = E⊥ cos θ`.
    Directional { direction: Vec3, irradiance: Vec3 },
    /// A one-sided emitting parallelogram `corner + s·edge_u + t·edge_v`, `s, t ∈ [0, 1]`, of
    /// uniform `radiance`, emitting on the side of `edge_u × edge_v`. Estimated with `samples`
    /// shadow rays to stratified points `y_k` (area `A`):
    /// `E ≈ (1/N) Σ_k L · cos θ_x · cos θ_y · A / |x − y_k|²` (the area form of the rendering
    /// equation's direct term; Shirley, Wang & Zimmerman 1996, "Monte Carlo techniques for direct
    /// lighting calculations").
    Rect {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
        radiance: Vec3,
        samples: u32,
    },
}

/// One shadow ray's worth of a light: where to look and what arrives if nothing is in the way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shaded point towards the light.
    pub direction: Vec3,
    /// Distance to the sampled point of the light; infinite for directional lights.
    pub distance: f32,
    /// Irradiance on a surface facing `direction` (the receiver's `cos θ` is not included),
    /// already divided by the light's number of samples.
    pub irradiance: Vec3,
}

impl Light {
    /// Shadow rays this light takes per shaded point.
    pub fn sample_count(&self) -> u32 {
        match self {
            Light::Rect { samples, .. } => *samples,
            _ => 1,
        }
    }

    /// Sample `k` of [`Light::sample_count`] seen from `point`; `None` when the light cannot
    /// reach the point (behind a one-sided area light, or at its very position).
    ///
    /// Area samples are stratified: with `N = n²` samples, `k` falls in cell `(k mod n, k / n)`
    /// of an `n × n` grid; otherwise in strip `k` of `N` strips along `edge_u`. The position
    /// inside the cell comes from `sampler`.
    pub fn sample(&self, point: Vec3, k: u32, sampler: &mut PixelSampler) -> Option<LightSample> {
        match *self {
            Light::Point {
                position,
                intensity,
            } => {
                let to_light = position - point;
                let d2 = to_light.length_squared();
                (d2 > 0.0).then(|| {
                    let distance = d2.sqrt();
                    LightSample {
                        direction: to_light / distance,
                        distance,
                        irradiance: intensity / d2,
                    }
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                direction: -direction,
                distance: f32::INFINITY,
                irradiance,
            }),
            Light::Rect {
                corner,
                edge_u,
                edge_v,
                radiance,
                samples,
            } => {
                let (s, t) = stratified(k, samples, sampler);
                let y = corner + s * edge_u + t * edge_v;
                let normal_area = edge_u.cross(edge_v);
                let to_light = y - point;
                let d2 = to_light.length_squared();
                if d2 <= 0.0 {
                    return None;
                }
                let distance = d2.sqrt();
                let direction = to_light / distance;
                // cos θ_y · A = −direction · (edge_u × edge_v), since |edge_u × edge_v| = A.
                let cos_area = -direction.dot(normal_area);
                (cos_area > 0.0).then(|| LightSample {
                    direction,
                    distance,
                    irradiance: radiance * (cos_area / (d2 * samples as f32)),
                })
            }
        }
    }
}

/// A point of cell `k` of `n` strata of the unit square (see [`Light::sample`]).
fn stratified(k: u32, n: u32, sampler: &mut PixelSampler) -> (f32, f32) {
    let side = (n as f64).sqrt().round() as u32;
    let (r1, r2) = (sampler.next_f32(), sampler.next_f32());
    if side * side == n {
        (
            ((k % side) as f32 + r1) / side as f32,
            ((k / side) as f32 + r2) / side as f32,
        )
    } else {
        ((k as f32 + r1) / n as f32, r2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_falls_off_with_the_square_of_distance() {
        let light = Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Vec3::splat(8.0),
        };
        let s = light
            .sample(Vec3::ZERO, 0, &mut PixelSampler::new(0))
            .unwrap();
        assert_eq!(s.direction, Vec3::Y);
        assert_eq!(s.distance, 2.0);
        assert_eq!(s.irradiance, Vec3::splat(2.0));
    }

    #[test]
    fn area_light_estimate_converges_to_the_analytic_irradiance() {
        // A small square of radiance L far above the point: E ≈ L·A/d².
        let light = Light::Rect {
            corner: Vec3::new(-0.05, 10.0, -0.05),
            edge_u: Vec3::new(0.1, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 0.1),
            radiance: Vec3::splat(100.0),
            samples: 16,
        };
        let mut sampler = PixelSampler::new(1);
        let e: f32 = (0..16)
            .map(|k| {
                light
                    .sample(Vec3::ZERO, k, &mut sampler)
                    .unwrap()
                    .irradiance
                    .x
            })
            .sum();
        assert!((e - 100.0 * 0.01 / 100.0).abs() < 1e-4, "{e}");
        // Seen from above (behind the emitting side) the light gives nothing.
        assert!(light
            .sample(Vec3::new(0.0, 20.0, 0.0), 0, &mut sampler)
            .is_none());
    }

    #[test]
    fn strata_cover_the_square() {
        let mut sampler = PixelSampler::new(3);
        for n in [1, 4, 9, 16, 5] {
            for k in 0..n {
                let (s, t) = stratified(k, n, &mut sampler);
                assert!((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t));
            }
        }
    }
}
