//! `threads=`: how many threads a query uses. `None`: one per core; `1`: the calling thread
//! itself, with no hand-off to a pool thread (on a busy machine each hand-off waits for the
//! scheduler, which can cost more than a small batch); `n`: `n` threads. Row-by-row queries
//! ([`fill_rows`]) run on the calling thread and `n - 1` threads of a pool; the others
//! ([`run_on_threads`]: `closest_point`'s sorted batches, `intersect_all`) on a pool of `n`
//! threads (the global rayon pool for `None`) while the calling thread waits. A pool of `n` is
//! started on first use and kept for later calls.

use std::sync::{Arc, Mutex};

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// Rows per run a thread takes: enough to hide scheduling, few enough to balance many cores.
pub const GRAIN: usize = 256;

/// Batches up to this many rows run on the calling thread alone, whatever `threads` says: they
/// take a few hundred microseconds at most, about what waking a pool's sleeping threads can
/// take on a virtual machine, and a call cannot return before the pool threads it asked for
/// have run (if only to find nothing left). Handed to the pool, 2,000 teapot rays took 280 µs
/// against 115 µs on the calling thread, 300 rays 58 µs against 19 µs (2 ms of other work
/// between calls; BENCHMARKS.md).
pub const SERIAL_ROWS: usize = 8 * GRAIN;

/// `threads=0`: an error, whatever the batch (checked before any work).
fn check(threads: Option<usize>) -> PyResult<()> {
    if threads == Some(0) {
        return Err(PyValueError::new_err(
            "threads: expected a positive number of threads, or None for all cores",
        ));
    }
    Ok(())
}

/// Runs `work` on all cores (`threads` = None) or on a pool of exactly `threads` threads.
pub fn run_on_threads<T: Send>(
    threads: Option<usize>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    check(threads)?;
    match threads {
        Some(n) if n > 0 => Ok(pool_of(n)?.install(work)),
        _ => Ok(work()),
    }
}

/// [`run_on_threads`], but on the calling thread when `here` (a batch whose work does not use
/// the pool, and should not wait for it to wake).
pub fn run_here_or_on_threads<T: Send>(
    here: bool,
    threads: Option<usize>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    check(threads)?;
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
/// thread and `threads - 1` of the pool's threads (every core but one for `None`) take in turn.
///
/// The calling thread starts on the first run at once, and the pool's threads join as they
/// wake: on a virtual machine a sleeping thread can take up to a millisecond to run, and the
/// caller would otherwise wait for it with nothing done. One thread fewer in the pool keeps
/// one thread per core (with the caller working too, a full pool would share a core between
/// two threads).
pub fn fill_rows<R: Rows>(
    threads: Option<usize>,
    rows: R,
    fill: impl Fn(usize, R) + Sync + Send,
) -> PyResult<()> {
    check(threads)?;
    if threads == Some(1) || rows.rows() <= SERIAL_ROWS {
        fill(0, rows);
        return Ok(());
    }
    let runs = Mutex::new(runs_of(rows).into_iter());
    let take_runs = || loop {
        let next = runs
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .next();
        match next {
            Some((first, run)) => fill(first, run),
            None => break,
        }
    };
    match threads {
        Some(n) => pool_of(n)?.in_place_scope(|scope| beside_caller(scope, n - 1, &take_runs)),
        None => rayon::in_place_scope(|scope| {
            beside_caller(scope, rayon::current_num_threads() - 1, &take_runs)
        }),
    }
    Ok(())
}

/// Runs `work` on the calling thread and on `helpers` of the scope's pool threads.
fn beside_caller<'s>(scope: &rayon::Scope<'s>, helpers: usize, work: &'s (impl Fn() + Sync)) {
    for _ in 0..helpers {
        scope.spawn(move |_| work());
    }
    work();
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
