//! Where a batch of queries runs (nearest points, every hit along rays): shared out between the calling thread and the current
//! rayon pool's other threads, or in turn on the calling thread alone. The same steps either
//! way, so the same answers; only who takes them differs.
//!
//! **Shared out** (`Threads::Pool`): the work is cut into items (runs of a batch) that the
//! calling thread starts on at once and the pool's threads take one at a time as they wake. A
//! rayon parallel iterator called from outside the pool would instead hand every item to the
//! pool and leave the calling thread waiting for a pool thread to wake (from Python, 100–200 µs
//! on an idle virtual machine before any answer, which made all-threads batches of up to 8,192
//! points slower than one-thread ones on the Cornell box).
//!
//! **On the calling thread** (`Threads::Here`): for a caller that wants one thread. A pool of
//! one gains nothing: its thread must be woken for each call, which on a busy machine waits for
//! the scheduler (from Python, 257 to 2,048 points took 2 ms at the 90th percentile through a
//! one-thread pool, against 0.17–0.8 ms of work, while two other processes ran).

use std::collections::VecDeque;
use std::sync::Mutex;

/// Where a batch runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Threads {
    /// The calling thread and the current rayon pool's other threads (the global pool's outside
    /// any pool), taking items in turn.
    Pool,
    /// In turn on the calling thread; no rayon task is made.
    Here,
}

/// Calls `f` on every item (module notes): each item once, in no particular order on `Pool`.
pub(crate) fn share_out<W: Send>(threads: Threads, items: Vec<W>, f: impl Fn(W) + Sync) {
    let helpers = match threads {
        Threads::Here => 0,
        // One thread per core with the caller working too (the caller, if it is a thread of
        // the pool, counts among them); never more helpers than items left for them.
        Threads::Pool => (rayon::current_num_threads() - 1).min(items.len().saturating_sub(1)),
    };
    if helpers == 0 {
        items.into_iter().for_each(f);
        return;
    }
    let queue = SpanQueue::new(items, helpers + 1);
    let take_items = |worker: usize| {
        while let Some(item) = queue.next(worker) {
            f(item);
        }
    };
    rayon::in_place_scope(|scope| {
        for worker in 1..=helpers {
            let take_items = &take_items;
            scope.spawn(move |_| take_items(worker));
        }
        take_items(0);
    });
}

/// A batch's items shared out between `workers` threads (numbered from 0) in spans of
/// consecutive items, one span per worker: a worker takes its own span's items first to last,
/// and once that is empty, the last item left of another's.
///
/// Consecutive items are neighbours in a batch's order (a camera's rows of rays, Morton-sorted
/// points), which visit the same nodes of a tree; a thread that takes them one after another
/// finds those nodes in its core's cache. Handed out in turn from one queue, each thread's
/// items were every other one, and both cores' caches held the whole batch's nodes (from
/// Python, camera rays on two threads gained 1.5–4 % with spans; BENCHMARKS.md). Taking the
/// others' *last* items keeps the balance of one queue (a thread that wakes late leaves its
/// span to the others, from its far end) without breaking the spans' runs.
///
/// Used by the nearest-point and every-hit batches here, and by the Python package's row-by-row
/// queries.
pub struct SpanQueue<W> {
    spans: Vec<Mutex<VecDeque<W>>>,
}

impl<W> SpanQueue<W> {
    /// `items` cut into `workers` spans of as equal lengths as can be (at least one span).
    pub fn new(items: Vec<W>, workers: usize) -> Self {
        let workers = workers.max(1);
        let n = items.len();
        let mut items = items.into_iter();
        let spans = (0..workers)
            .map(|w| {
                let len = (w + 1) * n / workers - w * n / workers;
                Mutex::new(items.by_ref().take(len).collect())
            })
            .collect();
        Self { spans }
    }

    /// The next item for `worker` (taken modulo the number of spans): the first left of its
    /// own span, else the last left of the next non-empty span after it; `None` when every
    /// span is empty.
    pub fn next(&self, worker: usize) -> Option<W> {
        let span = |k: usize| {
            self.spans[k % self.spans.len()]
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner())
        };
        if let Some(item) = span(worker).pop_front() {
            return Some(item);
        }
        (1..self.spans.len()).find_map(|k| span(worker + k).pop_back())
    }
}

/// Calls `f(k, chunk)` for the `k`-th chunk of `len` items of `items` (the last one shorter).
pub(crate) fn for_each_chunk<T: Send>(
    threads: Threads,
    items: &mut [T],
    len: usize,
    f: impl Fn(usize, &mut [T]) + Sync,
) {
    let chunks: Vec<_> = items.chunks_mut(len).enumerate().collect();
    share_out(threads, chunks, |(k, chunk)| f(k, chunk));
}

/// Items per chunk of [`map_collect`]: enough that taking one costs nothing beside its work.
const MAP_CHUNK: usize = 4096;

/// `(0..n).map(f)`, collected in order.
pub(crate) fn map_collect<T: Send + Copy + Default>(
    threads: Threads,
    n: usize,
    f: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    let mut out = vec![T::default(); n];
    for_each_chunk(threads, &mut out, MAP_CHUNK, |k, chunk| {
        for (j, slot) in chunk.iter_mut().enumerate() {
            *slot = f(k * MAP_CHUNK + j);
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Each worker takes its own span in order, then the others' from their far ends; every
    /// item once, for any number of workers (more workers than items included).
    #[test]
    fn spans_are_taken_in_order_then_from_the_far_end() {
        let queue = SpanQueue::new((0..10).collect(), 2);
        let first: Vec<_> = (0..3).map(|_| queue.next(0).unwrap()).collect();
        assert_eq!(first, [0, 1, 2]);
        assert_eq!(queue.next(1), Some(5));
        let rest: Vec<_> = std::iter::from_fn(|| queue.next(0)).collect();
        assert_eq!(rest, [3, 4, 9, 8, 7, 6]);
        assert_eq!(queue.next(1), None);
        for workers in [0, 1, 3, 7, 20] {
            let queue = SpanQueue::new((0..7).collect(), workers);
            let mut taken: Vec<_> = (0..14).filter_map(|k| queue.next(k % 5)).collect();
            taken.sort();
            assert_eq!(taken, (0..7).collect::<Vec<_>>());
        }
    }

    /// Every item is taken exactly once, on one thread or shared out, inside a pool and outside.
    #[test]
    fn every_item_is_taken_once() {
        for threads in [Threads::Here, Threads::Pool] {
            for n in [0, 1, 2, 7, 1000] {
                let taken: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
                share_out(threads, (0..n).collect(), |i| {
                    taken[i].fetch_add(1, Ordering::Relaxed);
                });
                assert!(taken.iter().all(|t| t.load(Ordering::Relaxed) == 1));
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(3)
                    .build()
                    .unwrap();
                let squares = pool.install(|| map_collect(threads, n, |i| i * i));
                assert_eq!(squares, (0..n).map(|i| i * i).collect::<Vec<_>>());
            }
        }
    }
}
