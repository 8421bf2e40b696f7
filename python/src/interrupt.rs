//! Ctrl-C while Rust computes: a job runs on a thread of its own while the
//! interpreter's thread checks Python's signals and raises the engine's
//! stop flag (`fit` and `diagnose` both run their work this way).

use std::time::Duration;

use pyo3::prelude::*;

use mckibben::fit::searches::StopFlag;

/// How often the interpreter checks for Ctrl-C while a job runs.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Runs `job` on a thread of its own with the interpreter detached, while
/// this thread checks Python's signals: on Ctrl-C (or any signal handler's
/// exception) it raises `stop`, waits for `job` to wind down (its searches
/// stop at their next generation) and returns the signal's exception.
pub(crate) fn interruptible<T: Send>(
    py: Python<'_>,
    stop: &StopFlag,
    job: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let worker = scope.spawn(job);
        loop {
            py.detach(|| std::thread::sleep(SIGNAL_POLL));
            if let Err(e) = py.check_signals() {
                stop.raise();
                // The job's own result (`Interrupted`) is not news.
                let _ = py.detach(|| worker.join());
                return Err(e);
            }
            if worker.is_finished() {
                // A panic goes on as this thread's (PyO3's PanicException).
                return Ok(worker
                    .join()
                    .unwrap_or_else(|p| std::panic::resume_unwind(p)));
            }
        }
    })
}
