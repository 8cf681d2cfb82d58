//! Single lanes of AVX registers: one lane read, a bit mask made a lane mask, the least lane.

use std::arch::x86_64::*;

use super::PACKET_RAYS;

/// Lane `lane` of `x`.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn lane_of(x: __m256, lane: usize) -> f32 {
    let mut values = [0.0f32; PACKET_RAYS];
    // SAFETY: the store writes the eight lanes into `values`.
    unsafe { _mm256_storeu_ps(values.as_mut_ptr(), x) };
    values[lane]
}

/// The lanes of bit mask `bits` as an AVX mask (all ones in lane `i` if bit `i` is set).
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn lane_mask(bits: u32) -> __m256 {
    let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let set = _mm256_and_si256(_mm256_set1_epi32(bits as i32), bit);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, bit))
}

/// The least of the eight lanes of `x`.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) unsafe fn horizontal_min(x: __m256) -> f32 {
    let x = _mm256_min_ps(x, _mm256_permute2f128_ps::<1>(x, x));
    let x = _mm256_min_ps(x, _mm256_shuffle_ps::<0b01_00_11_10>(x, x));
    let x = _mm256_min_ps(x, _mm256_shuffle_ps::<0b10_11_00_01>(x, x));
    _mm256_cvtss_f32(x)
}
