//! Placing a mesh in the scene: scale, then rotate, then translate.

use glam::{Affine3A, DAffine3, DQuat, Quat, Vec3};

/// An object's placement: `p ↦ translate + R(scale ⊙ p)`, where `R` rotates by
/// `rotate_degrees.x` about the x axis first, then `.y` about y, then `.z` about z (fixed axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub translate: Vec3,
    pub rotate_degrees: Vec3,
    pub scale: Vec3,
}

impl Default for Transform {
    /// The identity.
    fn default() -> Self {
        Transform {
            translate: Vec3::ZERO,
            rotate_degrees: Vec3::ZERO,
            scale: Vec3::ONE,
        }
    }
}

impl Transform {
    /// The affine map of this placement.
    pub fn to_affine(&self) -> Affine3A {
        let r = self.rotate_degrees * (std::f32::consts::PI / 180.0);
        let rotation =
            Quat::from_rotation_z(r.z) * Quat::from_rotation_y(r.y) * Quat::from_rotation_x(r.x);
        Affine3A::from_scale_rotation_translation(self.scale, rotation, self.translate)
    }

    /// The same map in f64 (its fields widened, the rotation made in f64).
    pub fn to_daffine(&self) -> DAffine3 {
        let r = self.rotate_degrees.as_dvec3().map(f64::to_radians);
        let rotation =
            DQuat::from_rotation_z(r.z) * DQuat::from_rotation_y(r.y) * DQuat::from_rotation_x(r.x);
        DAffine3::from_scale_rotation_translation(
            self.scale.as_dvec3(),
            rotation,
            self.translate.as_dvec3(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_then_rotates_then_translates() {
        let t = Transform {
            translate: Vec3::new(10.0, 0.0, 0.0),
            rotate_degrees: Vec3::new(0.0, 0.0, 90.0),
            scale: Vec3::splat(2.0),
        };
        let p = t.to_affine().transform_point3(Vec3::X);
        assert!((p - Vec3::new(10.0, 2.0, 0.0)).length() < 1e-5, "{p}");
        let q = t.to_daffine().transform_point3(glam::DVec3::X).as_vec3();
        assert!((q - p).length() < 1e-5, "{q}");
    }
}
