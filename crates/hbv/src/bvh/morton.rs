//! Morton (Z-order) codes of points in a box: sorting by them keeps nearby points together.

use glam::Vec3;

use crate::geometry::Aabb;

/// Bits per axis of [`morton_code`]: 3 × 21 = 63 bits.
pub const MORTON_BITS_PER_AXIS: u32 = 21;

/// The 63-bit Morton code of `p` quantised to a `2^21`-cell grid over `bounds`: the bits of the
/// three cell coordinates interleaved, x in the highest position (Morton 1966; as used by
/// Lauterbach et al. 2009 for LBVH). Points outside `bounds` are clamped onto it.
pub fn morton_code(p: Vec3, bounds: &Aabb) -> u64 {
    let cells = (1u32 << MORTON_BITS_PER_AXIS) as f32;
    let extent = bounds.extent().max(Vec3::splat(f32::MIN_POSITIVE));
    let q = ((p - bounds.min) / extent * cells).clamp(Vec3::ZERO, Vec3::splat(cells - 1.0));
    (spread_bits(q.x as u64) << 2) | (spread_bits(q.y as u64) << 1) | spread_bits(q.z as u64)
}

/// Spreads the low 21 bits of `x` so that bit `i` moves to bit `3i`.
pub(crate) fn spread_bits(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_moves_each_bit_to_three_times_its_position() {
        for i in 0..21 {
            assert_eq!(spread_bits(1 << i), 1 << (3 * i));
        }
        assert_eq!(spread_bits(0x1f_ffff), 0x1249_2492_4924_9249 | (1 << 60));
    }

    #[test]
    fn corners_and_order() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(morton_code(Vec3::ZERO, &b), 0);
        assert_eq!(morton_code(Vec3::ONE, &b), (1u64 << 63) - 1);
        assert!(
            morton_code(Vec3::new(0.6, 0.0, 0.0), &b) > morton_code(Vec3::new(0.4, 0.9, 0.9), &b)
        );
    }
}
