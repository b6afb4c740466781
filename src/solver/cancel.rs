//! A request to stop a run early, shared between whoever asks (the command
//! line on SIGINT/SIGTERM, a test) and the solvers, which check it at
//! their safe points: the quasi-static solver before every load step and
//! Newton iteration, the explicit solver every time increment. The solvers
//! never learn why.

use std::sync::atomic::{AtomicBool, Ordering};

/// A shared stop flag. Copies share the flag; [`CancelToken::default`]
/// can never be cancelled. It is `Copy` so that the solvers' parameters
/// stay plain values: the flag of a [`CancelToken::new`] lives for the rest
/// of the process (one byte; a command makes one per run).
#[derive(Debug, Clone, Copy, Default)]
pub struct CancelToken(Option<&'static AtomicBool>);

impl CancelToken {
    /// A fresh token, not cancelled.
    pub fn new() -> Self {
        Self(Some(Box::leak(Box::new(AtomicBool::new(false)))))
    }

    /// Asks every holder of this token to stop at its next safe point (no
    /// effect on a [`CancelToken::default`]).
    pub fn cancel(&self) {
        if let Some(flag) = self.0 {
            flag.store(true, Ordering::Relaxed);
        }
    }

    /// `true` once [`CancelToken::cancel`] was called on any copy.
    pub fn is_cancelled(&self) -> bool {
        self.0.is_some_and(|flag| flag.load(Ordering::Relaxed))
    }
}

/// A token is not a setting: every two compare equal, so that solver
/// parameters compare by their settings alone.
impl PartialEq for CancelToken {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_share_the_flag() {
        let token = CancelToken::new();
        let held = token;
        assert!(!held.is_cancelled());
        token.cancel();
        assert!(held.is_cancelled());
        assert!(!CancelToken::new().is_cancelled());
        let never = CancelToken::default();
        never.cancel();
        assert!(!never.is_cancelled());
    }
}
