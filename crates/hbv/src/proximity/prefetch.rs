//! A software prefetch: the hint the nearest-point batches give the CPU for memory they will
//! read a few queries later, at addresses the hardware prefetchers cannot guess (a candidate
//! grid's cells, answers gathered back into the callers' order).

/// Asks the CPU to load the cache line holding `address` into every cache level. A hint: it
/// reads nothing the program sees and never faults, whatever the address (one past the end,
/// or no object's at all); on other architectures it does nothing.
#[inline(always)]
pub(super) fn prefetch<T>(address: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `prefetcht0` is a hint; it never faults and changes no state the program reads.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(address.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = address;
}
