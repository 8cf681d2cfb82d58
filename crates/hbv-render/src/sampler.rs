//! Deterministic random numbers per pixel, so that an image does not depend on thread count or
//! tile order.

/// A PCG32 generator (O'Neill 2014, "PCG: a family of simple fast space-efficient statistically
/// good algorithms for random number generation"), seeded from the pixel's index in the image:
/// pixel `i` always draws the same sequence, whichever thread renders it and when.
#[derive(Clone, Debug)]
pub struct PixelSampler {
    state: u64,
    increment: u64,
}

const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

impl PixelSampler {
    /// The generator of pixel `index` (`y · width + x`).
    pub fn new(index: u64) -> Self {
        // Distinct odd increments give independent streams; the state is scrambled once so that
        // neighbouring pixels do not start from neighbouring states.
        let mut s = PixelSampler {
            state: 0,
            increment: (index << 1) | 1,
        };
        s.next_u32();
        s.state = s.state.wrapping_add(0x853c_49e6_748f_ea9b ^ index);
        s.next_u32();
        s
    }

    /// The next 32 random bits (PCG-XSH-RR).
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.increment);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform number in [0, 1): the top 24 bits, so that it is exact in `f32` and below 1.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_pixel_same_sequence_and_values_in_range() {
        let mut a = PixelSampler::new(42);
        let mut b = PixelSampler::new(42);
        let mut c = PixelSampler::new(43);
        let mut differs = false;
        for _ in 0..1000 {
            let x = a.next_f32();
            assert_eq!(x, b.next_f32());
            assert!((0.0..1.0).contains(&x));
            differs |= x != c.next_f32();
        }
        assert!(differs);
    }

    #[test]
    fn mean_is_about_one_half() {
        let mut s = PixelSampler::new(7);
        let mean: f64 = (0..10_000).map(|_| s.next_f32() as f64).sum::<f64>() / 10_000.0;
        assert!((mean - 0.5).abs() < 0.02, "{mean}");
    }
}
