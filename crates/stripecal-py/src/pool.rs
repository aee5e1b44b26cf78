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

use std::sync::mpsc::{channel, RecvTimeoutError};
use std::time::Duration;

use pyo3::prelude::*;
use stripecal::Cancel;

/// How often a cancellable run's waiting thread takes the GIL to run Python's signal
/// handlers.
const POLL: Duration = Duration::from_millis(50);

/// [`Python::detach`] with the closure run on rayon's pool (module docs).
pub trait Detach {
    fn detach_pool<T, F>(self, f: F) -> T
    where
        F: FnOnce() -> T + Send,
        T: Send;

    /// [`Detach::detach_pool`] that Ctrl-C can stop: the closure runs on rayon's pool
    /// while the calling thread waits for it, taking the GIL every [`POLL`] to run
    /// Python's signal handlers (on the main thread, where Python runs them). An
    /// exception a handler raises (`KeyboardInterrupt`) sets `cancel`, which the core
    /// checks between its steps, and is returned once the closure has returned; the
    /// closure's result is then dropped.
    fn detach_cancellable<T, F>(self, cancel: &Cancel, f: F) -> PyResult<T>
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

    fn detach_cancellable<T, F>(self, cancel: &Cancel, f: F) -> PyResult<T>
    where
        F: FnOnce() -> T + Send,
        T: Send,
    {
        let (out, raised) = self.detach(|| {
            let (tx, rx) = channel();
            std::thread::scope(|s| {
                let worker = s.spawn(move || {
                    // the receiver waits until it has this or the worker has ended
                    let _ = tx.send(rayon::scope(|_| f()));
                });
                let mut raised = None;
                loop {
                    match rx.recv_timeout(POLL) {
                        Ok(out) => return (out, raised),
                        Err(RecvTimeoutError::Timeout) if raised.is_none() => {
                            if let Err(e) = Python::attach(|py| py.check_signals()) {
                                cancel.cancel();
                                raised = Some(e);
                            }
                        }
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => {
                            // the worker ended without a result: it panicked; the panic
                            // goes on as detach_pool's would
                            let payload = worker
                                .join()
                                .expect_err("a worker that sent nothing has panicked");
                            std::panic::resume_unwind(payload)
                        }
                    }
                }
            })
        });
        match raised {
            Some(e) => Err(e),
            None => Ok(out),
        }
    }
}
