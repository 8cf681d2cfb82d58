//! Linear radiance to display values: the sRGB transfer function (IEC 61966-2-1).

use glam::Vec3;

/// Encodes one linear value in [0, 1] with the sRGB curve:
/// `12.92·c` for `c ≤ 0.0031308`, else `1.055·c^(1/2.4) − 0.055` (IEC 61966-2-1:1999).
/// Values outside [0, 1] are clamped first; NaN encodes as 0.
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// A linear colour as three 8-bit sRGB values (rounded to nearest).
pub fn to_srgb8(c: Vec3) -> [u8; 3] {
    let q = |x: f32| (linear_to_srgb(x) * 255.0 + 0.5) as u8;
    [q(c.x), q(c.y), q(c.z)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_matches_the_standard() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        // Linear segment, and the two branches meet at the threshold.
        assert!((linear_to_srgb(0.002) - 0.02584).abs() < 1e-6);
        let below = linear_to_srgb(0.003_130_8);
        let above = 1.055 * 0.003_130_8f32.powf(1.0 / 2.4) - 0.055;
        assert!((below - above).abs() < 1e-4);
        // Middle grey 0.18 is about 46% in sRGB (118/255).
        assert_eq!(to_srgb8(Vec3::splat(0.18)), [118, 118, 118]);
        assert_eq!(to_srgb8(Vec3::new(-1.0, 2.0, f32::NAN)), [0, 255, 0]);
    }
}
