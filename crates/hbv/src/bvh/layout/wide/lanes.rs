//! Lane masks: bit `i` of a `u32` for SIMD lane `i` (a box, a triangle or a ray), and the lanes
//! set in one, lowest first.

/// The set bits of a lane mask, lowest first. Holds only the mask, so the ray it came from may be
/// changed (its `tmax` shrunk) while the lanes are visited.
pub(crate) struct Lanes(pub u32);

impl Iterator for Lanes {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let lane = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(lane)
    }
}
