//! The extension's memory allocator: mimalloc, set to hand freed memory back to the kernel
//! lazily, so that a query's answer arrays do not fault their pages in afresh on every call.
//!
//! Every answer column is a Rust `Vec` handed to NumPy, and freed through this allocator when
//! Python drops the array. With the C library's allocator, a process's heap history decided
//! whether those megabytes were given back to the kernel at once (glibc trims the heap's top)
//! and then faulted in again, page by page, by the next call: about 1 µs a page on the
//! benchmark's virtual machine, 992 pages (a fifth of the time) on every one-thread camera-ray
//! call of the Cornell box inside `bench/python_compare.py`, none in another process.
//!
//! mimalloc keeps freed memory for a while, then *purges* it. By default a purge decommits
//! (`MADV_DONTNEED`): the pages are gone, and the next use faults them in again (measured: 418
//! faults a call on the teapot's random rays, since the benchmark's calls are further apart than
//! the purge delay). Here a purge resets instead (`MADV_FREE`): the kernel takes the pages back
//! only when it needs memory, and until then touching them again costs nothing. The price is
//! that the resident size (`top`'s RES) falls only when the kernel reclaims. The environment
//! variable `MIMALLOC_PURGE_DECOMMITS=1` restores mimalloc's default.

use std::ffi::c_long;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// `mi_option_purge_decommits` of mimalloc's `mi_option_t` (`mimalloc.h`; the `libmimalloc-sys`
/// crate names no constant for it).
const PURGE_DECOMMITS: libmimalloc_sys::mi_option_t = 5;

/// Sets the allocator's purges to reset rather than decommit (module notes), unless the user
/// chose with `MIMALLOC_PURGE_DECOMMITS`. Called once, when the module is imported.
pub fn configure() {
    if std::env::var_os("MIMALLOC_PURGE_DECOMMITS").is_none() {
        // SAFETY: an option index of mimalloc's table; called while importing the module,
        // before any of the module's threads exist.
        unsafe { libmimalloc_sys::mi_option_set(PURGE_DECOMMITS, 0 as c_long) };
    }
}
