//! Cooperative cancellation: a flag another thread sets (a Ctrl-C handler, a user
//! interface's stop button) and a long computation checks between its steps, returning
//! [`Error::Cancelled`] at the next check. Nothing is returned from a cancelled run, so
//! nothing half-done can be written.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::error::{Error, Result};

/// A handle to one cancellation flag; clones share it. The default handle is a fresh
/// flag that nobody else holds (never set).
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A fresh flag, not set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks every computation holding this flag (or a clone of it) to stop at its next
    /// check.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`Cancel::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// `Err(`[`Error::Cancelled`]`)` once the flag is set: the check between steps.
    pub fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }
}

/// A handle is not a setting: options that differ only in their handles are equal.
impl PartialEq for Cancel {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clone_sees_the_cancel_and_a_fresh_flag_does_not() {
        let a = Cancel::new();
        let b = a.clone();
        assert!(a.check().is_ok() && !b.is_cancelled());
        b.cancel();
        assert!(matches!(a.check(), Err(Error::Cancelled)));
        assert!(Cancel::default().check().is_ok());
    }
}
