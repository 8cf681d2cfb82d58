//! Where a batch of point queries runs: spread over the current rayon pool, or on the calling
//! thread alone. The same steps either way, so the same answers; only who takes them differs.
//!
//! A caller that wants one thread gains nothing from a pool of one: its thread must be woken
//! for each call, which on a busy machine waits for the scheduler (from Python, 257 to 2,048
//! points took 2 ms at the 90th percentile through a one-thread pool, against 0.17–0.8 ms of
//! work, while two other processes ran).

use rayon::prelude::*;

/// Where a batch runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Threads {
    /// In parallel on the current rayon pool (the global one outside any pool).
    Pool,
    /// In turn on the calling thread; no rayon task is made.
    Here,
}

/// `(0..n).map(f)`, collected in order.
pub(super) fn map_collect<T: Send>(
    threads: Threads,
    n: usize,
    f: impl Fn(usize) -> T + Sync + Send,
) -> Vec<T> {
    match threads {
        Threads::Pool => (0..n).into_par_iter().map(f).collect(),
        Threads::Here => (0..n).map(f).collect(),
    }
}

/// Calls `f(k, chunk)` for the `k`-th chunk of `len` items of `items` (the last one shorter).
pub(super) fn for_each_chunk<T: Send>(
    threads: Threads,
    items: &mut [T],
    len: usize,
    f: impl Fn(usize, &mut [T]) + Sync + Send,
) {
    match threads {
        Threads::Pool => items
            .par_chunks_mut(len)
            .enumerate()
            .for_each(|(k, chunk)| f(k, chunk)),
        Threads::Here => items
            .chunks_mut(len)
            .enumerate()
            .for_each(|(k, chunk)| f(k, chunk)),
    }
}
