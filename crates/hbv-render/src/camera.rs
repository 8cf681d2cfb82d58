//! The pinhole camera: pixel positions to primary rays.

use glam::Vec3;
use hbv::geometry::Ray;

/// A pinhole camera at `position` looking at `look_at`, with `up` fixing the roll and a vertical
/// field of view of `fov_y_degrees`; the image plane is `width × height` pixels.
///
/// Pixel `(x, y)` (x to the right, y downwards, from the top-left corner) and an offset
/// `(dx, dy) ∈ [0,1)²` inside it map to the direction
/// `forward + (2(x+dx)/W − 1)·tan(fov/2)·aspect·right + (1 − 2(y+dy)/H)·tan(fov/2)·up'`,
/// with `right = forward × up` and `up' = right × forward` (a right-handed frame whose image
/// `x` axis points right when `up` points up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub fov_y_degrees: f32,
}

/// The camera's frame, precomputed for one image size.
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    origin: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    width: f32,
    height: f32,
}

impl Camera {
    /// A placeholder (at the origin, looking down −z) for scenes that frame themselves later.
    pub fn default_for_bounds() -> Self {
        Camera {
            position: Vec3::ZERO,
            look_at: -Vec3::Z,
            up: Vec3::Y,
            fov_y_degrees: 45.0,
        }
    }

    /// The frame for a `width × height` image. The caller has checked that position, look-at and
    /// up span a frame (see [`Camera::frame_error`]).
    pub fn rays(&self, width: u32, height: u32) -> CameraRays {
        let forward = (self.look_at - self.position).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        let half_height = (self.fov_y_degrees.to_radians() / 2.0).tan();
        let half_width = half_height * width as f32 / height as f32;
        CameraRays {
            origin: self.position,
            forward,
            right: right * half_width,
            up: up * half_height,
            width: width as f32,
            height: height as f32,
        }
    }

    /// Why this camera cannot make rays, if it cannot.
    pub fn frame_error(&self) -> Option<&'static str> {
        let forward = self.look_at - self.position;
        if !(self.position.is_finite() && self.look_at.is_finite() && self.up.is_finite()) {
            Some("position, look_at and up must be finite")
        } else if forward.length_squared() == 0.0 {
            Some("look_at equals position")
        } else if forward.normalize().cross(self.up).length_squared() < 1e-12 {
            Some("up is zero or parallel to the viewing direction")
        } else if !(self.fov_y_degrees > 0.0 && self.fov_y_degrees < 180.0) {
            Some("fov must be between 0 and 180 degrees")
        } else {
            None
        }
    }
}

impl CameraRays {
    /// The primary ray through pixel `(x, y)` at offset `(dx, dy)` inside it (`0.5, 0.5` is the
    /// pixel's centre). The direction is normalized, so hit distances are in scene units.
    pub fn ray(&self, x: u32, y: u32, dx: f32, dy: f32) -> Ray {
        let sx = 2.0 * (x as f32 + dx) / self.width - 1.0;
        let sy = 1.0 - 2.0 * (y as f32 + dy) / self.height;
        let direction = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.origin, direction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: Vec3::ZERO,
            look_at: Vec3::new(0.0, 0.0, -1.0),
            up: Vec3::Y,
            fov_y_degrees: 90.0,
        }
    }

    #[test]
    fn centre_ray_looks_at_the_target() {
        let rays = camera().rays(100, 50);
        let r = rays.ray(50, 25, 0.0, 0.0);
        assert!((r.direction - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        assert_eq!(r.origin, Vec3::ZERO);
    }

    #[test]
    fn corners_span_the_field_of_view_and_aspect() {
        // 90° vertical: the top edge is at 45° up; aspect 2 doubles the horizontal extent.
        let rays = camera().rays(100, 50);
        let top_left = rays.ray(0, 0, 0.0, 0.0).direction;
        let d = top_left / -top_left.z;
        assert!((d - Vec3::new(-2.0, 1.0, -1.0)).length() < 1e-5, "{d}");
        let bottom_right = rays.ray(99, 49, 1.0, 1.0).direction;
        let d = bottom_right / -bottom_right.z;
        assert!((d - Vec3::new(2.0, -1.0, -1.0)).length() < 1e-5, "{d}");
    }

    #[test]
    fn degenerate_frames_are_reported() {
        let mut c = camera();
        assert!(c.frame_error().is_none());
        c.up = Vec3::new(0.0, 0.0, 2.0);
        assert!(c.frame_error().is_some());
        c = camera();
        c.look_at = c.position;
        assert!(c.frame_error().is_some());
        c = camera();
        c.fov_y_degrees = 180.0;
        assert!(c.frame_error().is_some());
    }
}
