//! Mirror reflection, Snell refraction and the Fresnel reflectance of a dielectric.
//!
//! Directions point *away from* the surface for the incoming light (`wo`, towards the viewer) and
//! normals face the side the ray arrives from, as in Pharr, Jakob & Humphreys, *Physically Based
//! Rendering* (4th ed.), §9.3–9.4.

use glam::Vec3;

/// Mirror reflection of `wo` (pointing away from the surface) about `n`: `wr = −wo + 2(wo·n)n`.
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    -wo + 2.0 * wo.dot(n) * n
}

/// Refraction of `wo` (pointing away from the surface, on `n`'s side) into the other medium,
/// with `eta = η_transmitted / η_incident`. Snell's law `sin θt = sin θi / eta` gives
/// `wt = −wo/eta + (cos θi/eta − cos θt) n`; `None` for total internal reflection (`sin θt > 1`).
pub fn refract(wo: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = wo.dot(n);
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wo / eta + (cos_i / eta - cos_t) * n)
}

/// Fresnel reflectance of unpolarized light at a smooth dielectric boundary (the mean of the
/// s- and p-polarized Fresnel equations), for `cos_i = cos θi ≥ 0` on the incident side and
/// `eta = η_t / η_i`:
///
/// `r∥ = (η cos θi − cos θt)/(η cos θi + cos θt)`, `r⊥ = (cos θi − η cos θt)/(cos θi + η cos θt)`,
/// `F = (r∥² + r⊥²)/2`; 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (r_par * r_par + r_perp * r_perp) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence_is_schlicks_r0() {
        // ((η−1)/(η+1))² = 0.04 for glass.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything.
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        // Brewster's angle: tan θB = η, the p-polarized part vanishes, F = r⊥²/2 ≈ 0.0730.
        let theta_b = 1.5f32.atan();
        assert!((fresnel_dielectric(theta_b.cos(), 1.5) - 0.0730).abs() < 1e-3);
        // Leaving glass beyond the critical angle (asin(1/1.5) ≈ 41.8°): total reflection.
        assert_eq!(fresnel_dielectric(45f32.to_radians().cos(), 1.0 / 1.5), 1.0);
        // Inside the critical angle some light leaves.
        assert!(fresnel_dielectric(30f32.to_radians().cos(), 1.0 / 1.5) < 0.5);
    }

    #[test]
    fn refraction_obeys_snell_and_total_internal_reflection() {
        let n = Vec3::Z;
        let theta_i = 30f32.to_radians();
        let wo = Vec3::new(theta_i.sin(), 0.0, theta_i.cos());
        let wt = refract(wo, n, 1.5).unwrap();
        assert!((wt.length() - 1.0).abs() < 1e-5);
        assert!(
            wt.z < 0.0 && wt.x < 0.0,
            "goes through, on the other side of the normal"
        );
        let sin_t = (wt.x * wt.x + wt.y * wt.y).sqrt();
        assert!(
            (theta_i.sin() - 1.5 * sin_t).abs() < 1e-5,
            "sin θi = η sin θt"
        );
        // Straight through at normal incidence.
        assert!((refract(Vec3::Z, n, 1.5).unwrap() + Vec3::Z).length() < 1e-6);
        // From glass to air at 45° (beyond the critical angle 41.8°): none.
        let theta = 45f32.to_radians();
        let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
        assert!(refract(wo, n, 1.0 / 1.5).is_none());
        let theta = 40f32.to_radians();
        let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
        assert!(refract(wo, n, 1.0 / 1.5).is_some());
    }

    #[test]
    fn reflection_mirrors_about_the_normal() {
        let wo = Vec3::new(1.0, 0.0, 1.0).normalize();
        let wr = reflect(wo, Vec3::Z);
        assert!((wr - Vec3::new(-1.0, 0.0, 1.0).normalize()).length() < 1e-6);
    }
}
