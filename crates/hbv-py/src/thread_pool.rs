//! `threads=`: how many threads a query uses. `None`: one per core; `1`: the calling thread
//! itself, with no hand-off to a pool thread (on a busy machine each hand-off waits for the
//! scheduler, which can cost more than a small batch), for every query; `n`: `n` threads.
//! Row-by-row queries ([`fill_rows`]) run on the calling thread and a pool of `n - 1` threads;
//! the others ([`run_on_threads`]: `closest_point`'s sorted batches, `intersect_all`) in a pool
//! of `n` threads (the global rayon pool for `None`, where `closest_point`'s runs are shared
//! between the calling thread and the pool's threads, hbv's `batch_threads`; for `n`, the
//! calling thread waits). A pool of `n` threads is started on first use and kept for later
//! calls.

use std::sync::{Arc, Mutex};

use hbv::batch_threads::SpanQueue;

use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyInt};

/// Rows per run a thread takes: enough to hide scheduling, few enough to balance many cores.
pub const GRAIN: usize = 256;

/// Batches up to this many rows run on the calling thread alone, whatever `threads` says: they
/// take a few hundred microseconds at most, about what waking a pool's sleeping threads can
/// take on a virtual machine, and a call cannot return before the pool threads it asked for
/// have run (if only to find nothing left). Handed to the pool, 2,000 teapot rays took 280 µs
/// against 115 µs on the calling thread, 300 rays 58 µs against 19 µs (2 ms of other work
/// between calls; BENCHMARKS.md).
pub const SERIAL_ROWS: usize = 8 * GRAIN;

/// The most threads `threads=` may ask for: starting 100,000 took minutes, for no gain on any
/// machine.
pub const MAX_THREADS: usize = 1024;

/// A `threads=` count as Python gives it: a positive integer (`None`, every core, is the
/// `Option` around it). Zero, negative, fractional and non-numeric counts are refused when the
/// arguments are read, before any work, with one message naming the argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ThreadCount(usize);

impl ThreadCount {
    /// The number of threads, at least 1.
    pub fn get(self) -> usize {
        self.0
    }
}

/// Whether a query asked for one thread: it then runs on the calling thread, with no pool.
pub fn one_thread(threads: Option<ThreadCount>) -> bool {
    threads.is_some_and(|n| n.get() == 1)
}

impl<'a, 'py> FromPyObject<'a, 'py> for ThreadCount {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let refused = || {
            let message = format!(
                "threads: expected a positive number of threads, or None for all cores; got {}",
                obj.repr()
                    .map_or_else(|_| "?".to_owned(), |r| r.to_string())
            );
            if obj.is_instance_of::<PyInt>() && !obj.is_instance_of::<PyBool>() {
                PyValueError::new_err(message)
            } else {
                PyTypeError::new_err(message)
            }
        };
        // bool is an int in Python, but `threads=True` is surely a mistake.
        if obj.is_instance_of::<PyBool>() {
            return Err(refused());
        }
        match obj.extract::<i64>() {
            Ok(n) if n > MAX_THREADS as i64 => Err(PyValueError::new_err(format!(
                "threads: at most {MAX_THREADS}, or None for all cores; got {n}"
            ))),
            Ok(n) if n >= 1 => usize::try_from(n).map(Self).map_err(|_| refused()),
            _ => Err(refused()),
        }
    }
}

/// Runs `work` on all cores (`threads` = None) or on a pool of exactly `threads` threads.
pub fn run_on_threads<T: Send>(
    threads: Option<ThreadCount>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    match threads {
        Some(n) => Ok(pool_of(n.get())?.install(work)),
        None => Ok(work()),
    }
}

/// [`run_on_threads`], but on the calling thread when `here` (a batch whose work does not use
/// the pool, and should not wait for it to wake).
pub fn run_here_or_on_threads<T: Send>(
    here: bool,
    threads: Option<ThreadCount>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    if here {
        return Ok(work());
    }
    run_on_threads(threads, work)
}

/// The pool of `n` threads, started on first use and kept: a query with `threads=n` would
/// otherwise start and stop `n` threads on every call (hundreds of microseconds, more than a
/// small batch takes).
fn pool_of(n: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    static POOLS: Mutex<Vec<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(Vec::new());
    let mut pools = POOLS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((_, pool)) = pools.iter().find(|(threads, _)| *threads == n) {
        return Ok(Arc::clone(pool));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start {n} threads: {e}")))?;
    let pool = Arc::new(pool);
    pools.push((n, Arc::clone(&pool)));
    Ok(pool)
}

/// Output columns of a query, one row per ray or point, that can be cut in two at a row.
pub trait Rows: Sized + Send {
    fn rows(&self) -> usize;
    fn split_at(self, row: usize) -> (Self, Self);
}

impl<T: Send> Rows for &mut [T] {
    fn rows(&self) -> usize {
        self.len()
    }
    fn split_at(self, row: usize) -> (Self, Self) {
        self.split_at_mut(row)
    }
}

/// A column only some queries have (a scene's `instance`): cut alongside the others when
/// present. Its row count is not asked (it is the second of a pair).
impl<R: Rows> Rows for Option<R> {
    fn rows(&self) -> usize {
        self.as_ref().map_or(0, Rows::rows)
    }
    fn split_at(self, row: usize) -> (Self, Self) {
        match self {
            Some(rows) => {
                let (a, b) = rows.split_at(row);
                (Some(a), Some(b))
            }
            None => (None, None),
        }
    }
}

impl<A: Rows, B: Rows> Rows for (A, B) {
    fn rows(&self) -> usize {
        self.0.rows()
    }
    fn split_at(self, row: usize) -> (Self, Self) {
        let (a0, a1) = self.0.split_at(row);
        let (b0, b1) = self.1.split_at(row);
        ((a0, b0), (a1, b1))
    }
}

/// Fills `rows` with `fill(first_row, rows)`: on the calling thread alone for `threads = Some(1)`
/// or at most [`SERIAL_ROWS`] rows; otherwise cut into runs of [`GRAIN`] rows that the calling
/// thread and a pool of `threads - 1` threads (one per core but one for `None`) take in spans
/// of consecutive runs, one per thread (`hbv::batch_threads::SpanQueue`: neighbouring rays
/// visit the same nodes, which then stay in one core's cache).
///
/// The calling thread starts on the first run at once, and the pool's threads join as they
/// wake: on a virtual machine a sleeping thread can take up to a millisecond to run, and the
/// caller would otherwise wait for it with nothing done. The pool has one thread fewer than
/// the count, so that with the caller working too there is one thread per core, and no idle
/// pool thread looking for work beside them.
pub fn fill_rows<R: Rows>(
    threads: Option<ThreadCount>,
    rows: R,
    fill: impl Fn(usize, R) + Sync + Send,
) -> PyResult<()> {
    let workers = threads.map_or_else(rayon::current_num_threads, ThreadCount::get);
    if workers == 1 || rows.rows() <= SERIAL_ROWS {
        fill(0, rows);
        return Ok(());
    }
    let queue = SpanQueue::new(runs_of(rows), workers);
    let take_runs = |worker: usize| {
        while let Some((first, run)) = queue.next(worker) {
            fill(first, run);
        }
    };
    pool_of(workers - 1)?.in_place_scope(|scope| beside_caller(scope, workers - 1, &take_runs));
    Ok(())
}

/// Runs `work(worker)` on the calling thread (worker 0) and on `helpers` of the scope's pool
/// threads (workers 1 to `helpers`).
fn beside_caller<'s>(scope: &rayon::Scope<'s>, helpers: usize, work: &'s (impl Fn(usize) + Sync)) {
    for worker in 1..=helpers {
        scope.spawn(move |_| work(worker));
    }
    work(0);
}

/// `rows` cut into runs of [`GRAIN`] rows (the last one shorter), each with its first row.
fn runs_of<R: Rows>(rows: R) -> Vec<(usize, R)> {
    let mut runs = Vec::with_capacity(rows.rows().div_ceil(GRAIN));
    let mut rest = rows;
    let mut first = 0;
    while rest.rows() > GRAIN {
        let (run, tail) = rest.split_at(GRAIN);
        runs.push((first, run));
        first += GRAIN;
        rest = tail;
    }
    runs.push((first, rest));
    runs
}
