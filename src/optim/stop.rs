//! The flag that stops a search between generations: Ctrl-C, Python's
//! `KeyboardInterrupt`, or a caller that has seen enough.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A flag that stops every search that reads it after its current
/// generation or polish iteration (Ctrl-C, Python's `KeyboardInterrupt`).
#[derive(Debug, Clone, Default)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    pub fn raise(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    pub fn raised(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    /// The flag as the engine reads it between generations.
    pub(crate) fn as_atomic(&self) -> &AtomicBool {
        &self.0
    }
}
