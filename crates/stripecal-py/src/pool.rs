//! Work done without the GIL runs as ONE job on rayon's pool ([`Detach::detach_pool`]).
//!
//! The core's parallel loops (`par_iter`) started from a thread outside the pool, as
//! Python's thread is, each hand their work to the pool and wait for it: a wake-up and a
//! hand-back per loop, which a calibration with dozens of loops pays dozens of times (with
//! `RAYON_NUM_THREADS=1`, 0.7 ms of a 5 ms profiler adjustment). Run from inside the pool
//! (`rayon::scope` takes the calling thread's job to a worker), the loops split their
//! work on the pool directly and the hand-off happens once.
//!
//! Not for work that calls back into Python with a progress callback: the callback
//! checks for signals (Ctrl-C), which Python handles on its main thread only, so those
//! calls keep `Python::detach` on the calling thread.

use pyo3::prelude::*;

/// [`Python::detach`] with the closure run on rayon's pool (module docs).
pub trait Detach {
    fn detach_pool<T, F>(self, f: F) -> T
    where
        F: FnOnce() -> T + Send,
        T: Send;
}

impl Detach for Python<'_> {
    fn detach_pool<T, F>(self, f: F) -> T
    where
        F: FnOnce() -> T + Send,
        T: Send,
    {
        self.detach(|| rayon::scope(|_| f()))
    }
}
